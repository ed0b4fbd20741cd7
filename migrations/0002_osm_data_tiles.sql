-- Raw OSM data per fixed-zoom data tile: an Overpass answer, or an import written in the same
-- Overpass JSON layout. Only complete, valid answers are ever stored.
CREATE TABLE osm_data_tiles (
    z          INTEGER NOT NULL,
    x          INTEGER NOT NULL,
    y          INTEGER NOT NULL,
    body       BLOB    NOT NULL,
    -- xxh3 of the body: a refresh that brings the same data changes nothing.
    hash       TEXT    NOT NULL,
    -- 'overpass' or 'import' (imported tiles are not refreshed from upstream).
    source     TEXT    NOT NULL,
    fetched_at INTEGER NOT NULL,
    PRIMARY KEY (z, x, y)
);
