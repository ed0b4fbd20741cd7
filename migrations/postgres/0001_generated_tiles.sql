-- Generated content under typed keys (see src/cache/key.rs), as the SQLite table of
-- migrations/0003_typed_tile_keys.sql.
CREATE TABLE generated_tiles (
    scheme       TEXT             NOT NULL,
    region       TEXT             NOT NULL,
    z            BIGINT           NOT NULL,
    x            BIGINT           NOT NULL,
    y            BIGINT           NOT NULL,
    encoding     TEXT             NOT NULL,
    roofs        TEXT             NOT NULL,
    data_version TEXT             NOT NULL,
    west         DOUBLE PRECISION NOT NULL,
    south        DOUBLE PRECISION NOT NULL,
    east         DOUBLE PRECISION NOT NULL,
    north        DOUBLE PRECISION NOT NULL,
    bytes        BYTEA            NOT NULL,
    etag         TEXT             NOT NULL,
    created_at   BIGINT           NOT NULL,
    size         BIGINT           NOT NULL,
    last_used    BIGINT           NOT NULL,
    PRIMARY KEY (scheme, region, z, x, y, encoding, roofs, data_version)
);
CREATE INDEX generated_tiles_area ON generated_tiles (west, east, south, north);
CREATE INDEX generated_tiles_last_used ON generated_tiles (last_used);
