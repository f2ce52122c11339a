-- Derived images of a result (the console's thumbnails,
-- GET /v1/brdfs/{id}/thumbnail), stored as blobs of their own: keyed by the
-- result's blob digest and the preview's kind (which names its renderer
-- version), so a result solved again gets new ones and older kinds are
-- never read. Removed with the result's blob (docs/service.md, "Previews").
CREATE TABLE previews (
  result_digest TEXT NOT NULL,
  kind TEXT NOT NULL,
  digest TEXT NOT NULL,
  size INTEGER NOT NULL,
  created_at INTEGER NOT NULL,
  PRIMARY KEY (result_digest, kind)
);
