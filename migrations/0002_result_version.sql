-- Which solver/schema version made a row (docs/service.md, "Ids and versions").
-- Rows written before this column existed were made by polbrdf-solver/2 or
-- earlier; they keep that label and are never served or solved again: the
-- service answers 410 for their ids and names the id of the current version.
ALTER TABLE jobs ADD COLUMN result_version TEXT NOT NULL DEFAULT 'polbrdf-spec/1 polbrdf-solver/2';
