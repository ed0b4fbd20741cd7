-- Following OpenStreetMap's replication diffs (src/source/data_tiles/replication/).
-- Where the stored buildings made from an element are: for each block of 256 ids of nodes
-- (kind 0), ways (1) or relations (2), the data tiles (zoom 14) holding a building made from
-- one of them. A diff's elements are found through it; a stale row only costs a read.
CREATE TABLE osm_element_tiles (
    kind  INTEGER NOT NULL,
    block INTEGER NOT NULL,
    x     INTEGER NOT NULL,
    y     INTEGER NOT NULL,
    PRIMARY KEY (kind, block, x, y)
) WITHOUT ROWID;
-- The last diff applied, written in the transaction that applied it: one row.
CREATE TABLE osm_replication (
    id         INTEGER PRIMARY KEY CHECK (id = 1),
    sequence   INTEGER NOT NULL,
    timestamp  TEXT    NOT NULL,
    url        TEXT    NOT NULL,
    applied_at INTEGER NOT NULL
);
-- Areas whose generated content a diff made stale, noted in the diff's transaction and deleted
-- once that content is dropped (a crash in between leaves them for the next run to drop).
CREATE TABLE osm_changed_areas (
    id    INTEGER PRIMARY KEY,
    west  REAL NOT NULL,
    south REAL NOT NULL,
    east  REAL NOT NULL,
    north REAL NOT NULL
);
