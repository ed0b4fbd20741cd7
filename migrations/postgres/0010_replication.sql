-- Following OpenStreetMap's replication diffs: as migrations/0015_replication.sql.
CREATE TABLE osm_element_tiles (
    kind  SMALLINT NOT NULL,
    block BIGINT   NOT NULL,
    x     BIGINT   NOT NULL,
    y     BIGINT   NOT NULL,
    PRIMARY KEY (kind, block, x, y)
);
CREATE TABLE osm_replication (
    id         INTEGER PRIMARY KEY CHECK (id = 1),
    sequence   BIGINT NOT NULL,
    timestamp  TEXT   NOT NULL,
    url        TEXT   NOT NULL,
    applied_at BIGINT NOT NULL
);
CREATE TABLE osm_changed_areas (
    id    BIGSERIAL PRIMARY KEY,
    west  DOUBLE PRECISION NOT NULL,
    south DOUBLE PRECISION NOT NULL,
    east  DOUBLE PRECISION NOT NULL,
    north DOUBLE PRECISION NOT NULL
);
