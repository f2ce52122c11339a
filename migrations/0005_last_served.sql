-- When a result was last served (ms since the Unix epoch; NULL: never since
-- it was made), for the eviction of the least recently served results
-- under --max-cache-bytes (docs/service.md, "Cache size"). Written at most
-- once a minute per result and instance.
ALTER TABLE jobs ADD COLUMN last_served_at INTEGER;
