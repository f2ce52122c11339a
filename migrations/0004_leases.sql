-- Leases of running jobs (docs/service.md, "The shared queue"): the
-- instance that claimed a running row (`lease_owner`, its --instance-id)
-- and when its claim lapses unless renewed (`lease_expires_at`, ms since
-- the Unix epoch). A running row whose lease has lapsed (or that has none:
-- rows written before this column existed) is queued again by any
-- instance. Both are NULL unless the row is running.
ALTER TABLE jobs ADD COLUMN lease_owner TEXT;
ALTER TABLE jobs ADD COLUMN lease_expires_at INTEGER;
CREATE INDEX jobs_leases ON jobs (lease_expires_at) WHERE status = 'running';
