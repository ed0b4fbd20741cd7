-- `citymesh export`'s work, shared by every exporter on this database
-- (src/commands/export/claims.rs): one row per export (what it writes, from which data), one
-- per unit of work (a tile of the world tree whose files one exporter writes under a lease).
CREATE TABLE exports (
    export     TEXT    PRIMARY KEY,
    describe   TEXT    NOT NULL,
    units      INTEGER NOT NULL,
    created_at INTEGER NOT NULL
);
CREATE TABLE export_units (
    export      TEXT    NOT NULL,
    id          INTEGER NOT NULL,
    z           INTEGER NOT NULL,
    x           INTEGER NOT NULL,
    y           INTEGER NOT NULL,
    -- The unit made from this one's summary, done only after it.
    parent      INTEGER,
    state       TEXT    NOT NULL DEFAULT 'pending',
    claim       INTEGER,
    lease_until INTEGER,
    -- Claims taken of it: more than one when an exporter died holding it, or stopped.
    attempts    INTEGER NOT NULL DEFAULT 0,
    files_est   INTEGER NOT NULL,
    files       INTEGER,
    summary     BLOB,
    PRIMARY KEY (export, id)
);
CREATE INDEX export_units_parent ON export_units (export, parent, state);
