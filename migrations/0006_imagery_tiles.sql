-- Imagery tiles fetched for the roof classifier (docs/method.md section 11), as the service sent
-- them, so a building classified again (another model, a changed footprint) costs no new fetch.
-- Rows older than --imagery-ttl-hours are fetched again; the least recently used go first when
-- the table outgrows --imagery-cache-mb.
CREATE TABLE imagery_tiles (
    imagery_id TEXT    NOT NULL,
    z          INTEGER NOT NULL,
    x          INTEGER NOT NULL,
    y          INTEGER NOT NULL,
    bytes      BLOB    NOT NULL,
    fetched_at INTEGER NOT NULL,
    last_used  INTEGER NOT NULL,
    PRIMARY KEY (imagery_id, z, x, y)
);
CREATE INDEX imagery_tiles_last_used ON imagery_tiles (last_used);
