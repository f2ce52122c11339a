-- Derived images of a result: migrations/0006_previews.sql in
-- PostgreSQL's types.
CREATE TABLE previews (
  result_digest TEXT NOT NULL,
  kind TEXT NOT NULL,
  digest TEXT NOT NULL,
  size BIGINT NOT NULL,
  created_at BIGINT NOT NULL,
  PRIMARY KEY (result_digest, kind)
);
