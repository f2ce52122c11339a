-- When a result was last served: migrations/0005_last_served.sql in
-- PostgreSQL's types.
ALTER TABLE jobs ADD COLUMN last_served_at BIGINT;
