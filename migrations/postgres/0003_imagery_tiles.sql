-- Imagery tiles fetched for the roof classifier, as the SQLite table of
-- migrations/0006_imagery_tiles.sql.
CREATE TABLE imagery_tiles (
    imagery_id TEXT   NOT NULL,
    z          BIGINT NOT NULL,
    x          BIGINT NOT NULL,
    y          BIGINT NOT NULL,
    bytes      BYTEA  NOT NULL,
    fetched_at BIGINT NOT NULL,
    last_used  BIGINT NOT NULL,
    PRIMARY KEY (imagery_id, z, x, y)
);
CREATE INDEX imagery_tiles_last_used ON imagery_tiles (last_used);
