-- `citymesh export`'s work, as migrations/0014_export_units.sql on SQLite.
CREATE TABLE exports (
    export     TEXT   PRIMARY KEY,
    describe   TEXT   NOT NULL,
    units      BIGINT NOT NULL,
    created_at BIGINT NOT NULL
);
CREATE TABLE export_units (
    export      TEXT   NOT NULL,
    id          BIGINT NOT NULL,
    z           BIGINT NOT NULL,
    x           BIGINT NOT NULL,
    y           BIGINT NOT NULL,
    parent      BIGINT,
    state       TEXT   NOT NULL DEFAULT 'pending',
    claim       BIGINT,
    lease_until BIGINT,
    -- Claims taken of it: more than one when an exporter died holding it, or stopped.
    attempts    BIGINT NOT NULL DEFAULT 0,
    files_est   BIGINT NOT NULL,
    files       BIGINT,
    summary     BYTEA,
    PRIMARY KEY (export, id)
);
CREATE INDEX export_units_parent ON export_units (export, parent, state);
