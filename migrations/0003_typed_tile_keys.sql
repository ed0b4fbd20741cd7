-- Generated content under typed keys (see src/cache/key.rs) instead of one variant string.
-- Cached bytes can always be generated again, so the old table is dropped, not converted.
DROP TABLE generated_tiles;
CREATE TABLE generated_tiles (
    -- 'xyz', 'implicit' (3D Tiles content) or 'bbox'.
    scheme       TEXT    NOT NULL,
    -- The implicit tree's root (minLon,minLat,maxLon,maxLat) or the box; '' for XYZ tiles.
    region       TEXT    NOT NULL,
    -- XYZ zoom/column/row, or implicit level/x/y (y from the south); 0 for a box.
    z            INTEGER NOT NULL,
    x            INTEGER NOT NULL,
    y            INTEGER NOT NULL,
    -- 'plain' so far.
    encoding     TEXT    NOT NULL,
    -- Where roof shapes came from: 'osm' (tags) so far.
    roofs        TEXT    NOT NULL,
    -- Generator version, DEM and --osm file fingerprints: rows of another version are never read.
    data_version TEXT    NOT NULL,
    -- The ground the content covers, degrees: a data change over it drops the row.
    west         REAL    NOT NULL,
    south        REAL    NOT NULL,
    east         REAL    NOT NULL,
    north        REAL    NOT NULL,
    bytes        BLOB    NOT NULL,
    etag         TEXT    NOT NULL,
    created_at   INTEGER NOT NULL,
    -- What the row costs on disk (length(bytes) and an estimate of page slack), summed to keep
    -- the store under --tile-store-mb.
    size         INTEGER NOT NULL,
    -- Milliseconds since the epoch of the last write or SQLite hit: the least recently used
    -- tiles are evicted first.
    last_used    INTEGER NOT NULL,
    PRIMARY KEY (scheme, region, z, x, y, encoding, roofs, data_version)
);
CREATE INDEX generated_tiles_area ON generated_tiles (west, east, south, north);
CREATE INDEX generated_tiles_last_used ON generated_tiles (last_used);
