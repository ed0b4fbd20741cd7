-- The OSM data fetched from Overpass is bounded in bytes: each data tile's size and when it was
-- last used, so the least recently used can be evicted (imported data never is).
ALTER TABLE osm_data_tiles ADD COLUMN size INTEGER NOT NULL DEFAULT 0;
ALTER TABLE osm_data_tiles ADD COLUMN last_used INTEGER NOT NULL DEFAULT 0;
UPDATE osm_data_tiles SET size = length(body), last_used = fetched_at * 1000;
CREATE INDEX osm_data_tiles_lru ON osm_data_tiles (source, last_used);
