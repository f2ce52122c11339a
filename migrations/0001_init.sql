-- The job/result index of `polbrdf serve` (docs/service.md, "Storage").
-- One row per spec id (content address of the canonical spec). A row is a
-- job while queued/running and the cached result once done; failed rows keep
-- the typed error. Result bytes live in the blob directory under their own
-- SHA-256 (`digest`); the row only points at them.
CREATE TABLE jobs (
    id            TEXT PRIMARY KEY NOT NULL,           -- 64 lowercase hex digits
    status        TEXT NOT NULL CHECK (status IN ('queued', 'running', 'done', 'failed')),
    spec          TEXT NOT NULL,                       -- canonical JSON of the spec
    wavelengths   INTEGER NOT NULL,                    -- number of solves (>= 1)
    progress      REAL NOT NULL DEFAULT 0,             -- fraction of wavelengths done, [0, 1]
    wall_time_ms  TEXT NOT NULL DEFAULT '[]',          -- JSON array, one entry per finished wavelength
    error_estimate REAL,                               -- NULL until the solver provides one
    error         TEXT,                                -- JSON problem object of a failed job
    digest        TEXT,                                -- SHA-256 of the result blob
    size          INTEGER,                             -- bytes of the result blob
    media_type    TEXT,                                -- media type of the result blob
    attempts      INTEGER NOT NULL DEFAULT 0,          -- solves started (crash-loop guard)
    created_at    INTEGER NOT NULL,                    -- ms since the Unix epoch
    updated_at    INTEGER NOT NULL,                    -- ms since the Unix epoch
    finished_at   INTEGER                              -- ms since the Unix epoch
);

CREATE INDEX jobs_unfinished ON jobs (status, created_at) WHERE status IN ('queued', 'running');
