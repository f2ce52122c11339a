-- The family of a row's spec (docs/service.md, "Covering results"): the id
-- of its canonical form without `needs`, `solver.streams` and
-- `solver.tolerance` (`plan::family_of_canonical`). A request is answered
-- from a done row of its family that holds everything it needs. Rows
-- written before this column existed get it when the index opens.
ALTER TABLE jobs ADD COLUMN family TEXT;
CREATE INDEX jobs_family ON jobs (family, finished_at) WHERE status = 'done';
