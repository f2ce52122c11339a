-- Leases of running jobs: migrations/0004_leases.sql in PostgreSQL's types
-- (this folder's 0001 is SQLite's 0001-0003, so the numbers meet here).
ALTER TABLE jobs ADD COLUMN lease_owner TEXT;
ALTER TABLE jobs ADD COLUMN lease_expires_at BIGINT;
CREATE INDEX jobs_leases ON jobs (lease_expires_at) WHERE status = 'running';
