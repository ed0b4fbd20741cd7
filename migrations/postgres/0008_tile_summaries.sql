-- The world tileset's tile summaries, as migrations/0013_tile_summaries.sql on SQLite.
CREATE TABLE tile_summaries (
    z            BIGINT           NOT NULL,
    x            BIGINT           NOT NULL,
    y            BIGINT           NOT NULL,
    data_version TEXT             NOT NULL,
    west         DOUBLE PRECISION NOT NULL,
    south        DOUBLE PRECISION NOT NULL,
    east         DOUBLE PRECISION NOT NULL,
    north        DOUBLE PRECISION NOT NULL,
    bytes        BYTEA            NOT NULL,
    PRIMARY KEY (z, x, y)
);
CREATE INDEX tile_summaries_area ON tile_summaries (west, east, south, north);
