-- Raw OSM data per data tile (an Overpass answer or an import), as the SQLite table of
-- migrations/0002_osm_data_tiles.sql and 0010_osm_store_bound.sql.
CREATE TABLE osm_data_tiles (
    z          BIGINT NOT NULL,
    x          BIGINT NOT NULL,
    y          BIGINT NOT NULL,
    body       BYTEA  NOT NULL,
    hash       TEXT   NOT NULL,
    source     TEXT   NOT NULL,
    fetched_at BIGINT NOT NULL,
    size       BIGINT NOT NULL DEFAULT 0,
    last_used  BIGINT NOT NULL DEFAULT 0,
    PRIMARY KEY (z, x, y)
);
CREATE INDEX osm_data_tiles_lru ON osm_data_tiles (source, last_used);
