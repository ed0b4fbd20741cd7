-- The world tileset's tile summaries (crates/citymesh-core/src/tiles3d/summary_bytes.rs), kept
-- so a restart reads them instead of making them again: one row per tile, of the data version
-- it was made for (another version is made again and replaces it). Dropped with the generated
-- tiles over any area whose data changes (src/cache/store/summaries.rs).
CREATE TABLE tile_summaries (
    z            INTEGER NOT NULL,
    x            INTEGER NOT NULL,
    y            INTEGER NOT NULL,
    data_version TEXT    NOT NULL,
    west         REAL    NOT NULL,
    south        REAL    NOT NULL,
    east         REAL    NOT NULL,
    north        REAL    NOT NULL,
    bytes        BLOB    NOT NULL,
    PRIMARY KEY (z, x, y)
);
CREATE INDEX tile_summaries_area ON tile_summaries (west, east, south, north);
