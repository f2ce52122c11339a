-- The job/result index of `polbrdf serve` in PostgreSQL (docs/service.md,
-- "Storage"): the schema the SQLite index has after migrations/0001-0003,
-- in PostgreSQL's types (BIGINT for counts, sizes and ms timestamps, DOUBLE
-- PRECISION for reals, TEXT for JSON), so that both backends store and
-- return the same values (src/storage/index). A later change of the schema
-- is a migration of the same number in both folders.
--
-- `id` collates as "C" (byte order, as SQLite compares text): keyset pages
-- (`created_at`, `id`) and ties order the same on both backends.
CREATE TABLE jobs (
    id             TEXT COLLATE "C" PRIMARY KEY NOT NULL, -- 64 lowercase hex digits
    status         TEXT NOT NULL CHECK (status IN ('queued', 'running', 'done', 'failed')),
    spec           TEXT NOT NULL,                    -- canonical JSON of the spec
    wavelengths    BIGINT NOT NULL,                  -- number of solves (>= 1)
    progress       DOUBLE PRECISION NOT NULL DEFAULT 0, -- fraction of wavelengths done, [0, 1]
    wall_time_ms   TEXT NOT NULL DEFAULT '[]',       -- JSON array, one entry per finished wavelength
    error_estimate DOUBLE PRECISION,                 -- NULL until the solver provides one
    error          TEXT,                             -- JSON problem object of a failed job
    digest         TEXT,                             -- SHA-256 of the result blob
    size           BIGINT,                           -- bytes of the result blob
    media_type     TEXT,                             -- media type of the result blob
    attempts       BIGINT NOT NULL DEFAULT 0,        -- solves started (crash-loop guard)
    created_at     BIGINT NOT NULL,                  -- ms since the Unix epoch
    updated_at     BIGINT NOT NULL,                  -- ms since the Unix epoch
    finished_at    BIGINT,                           -- ms since the Unix epoch
    -- Which solver/schema version made the row (docs/service.md, "Ids and
    -- versions"); the default is SQLite's (migrations/0002), for equality:
    -- every insert sets it.
    result_version TEXT NOT NULL DEFAULT 'polbrdf-spec/1 polbrdf-solver/2',
    -- The family of the row's spec (docs/service.md, "Covering results").
    family         TEXT
);

CREATE INDEX jobs_unfinished ON jobs (status, created_at) WHERE status IN ('queued', 'running');
CREATE INDEX jobs_family ON jobs (family, finished_at) WHERE status = 'done';
