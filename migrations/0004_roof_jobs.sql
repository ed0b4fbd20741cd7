-- Roof classification (docs/method.md section 11): batches asked for over HTTP or the command
-- line, one job per building and inputs, and the predictions they made.
CREATE TABLE roof_batches (
    id          INTEGER PRIMARY KEY AUTOINCREMENT,
    created_at  INTEGER NOT NULL,
    -- west,south,east,north as asked.
    bbox        TEXT    NOT NULL,
    imagery_id  TEXT    NOT NULL,
    model_id    TEXT    NOT NULL,
    -- Counts when the batch was made (JSON: queued, already, skipped by reason).
    counts      TEXT    NOT NULL,
    cancelled   INTEGER NOT NULL DEFAULT 0
);

-- A building is classified once per footprint, imagery and model: the unique key. A worker
-- claims a job by setting a lease; a job whose lease ran out (its worker died) is claimed again.
CREATE TABLE roof_jobs (
    id             INTEGER PRIMARY KEY AUTOINCREMENT,
    batch_id       INTEGER NOT NULL REFERENCES roof_batches (id),
    osm_id         TEXT    NOT NULL,
    footprint_hash TEXT    NOT NULL,
    imagery_id     TEXT    NOT NULL,
    model_id       TEXT    NOT NULL,
    -- The outer ring, JSON [[lon, lat], ...]: all a worker needs.
    footprint      TEXT    NOT NULL,
    -- queued, running, done, failed, cancelled
    state          TEXT    NOT NULL,
    attempts       INTEGER NOT NULL DEFAULT 0,
    lease_until    INTEGER,
    error          TEXT,
    updated_at     INTEGER NOT NULL,
    UNIQUE (osm_id, footprint_hash, imagery_id, model_id)
);
CREATE INDEX roof_jobs_claim ON roof_jobs (state, lease_until);
CREATE INDEX roof_jobs_batch ON roof_jobs (batch_id, state);

CREATE TABLE roof_predictions (
    osm_id         TEXT    NOT NULL,
    footprint_hash TEXT    NOT NULL,
    imagery_id     TEXT    NOT NULL,
    model_id       TEXT    NOT NULL,
    p_flat         REAL    NOT NULL,
    p_gabled       REAL    NOT NULL,
    p_hipped       REAL    NOT NULL,
    footprint      TEXT    NOT NULL,
    min_lon        REAL    NOT NULL,
    min_lat        REAL    NOT NULL,
    max_lon        REAL    NOT NULL,
    max_lat        REAL    NOT NULL,
    created_at     INTEGER NOT NULL,
    PRIMARY KEY (osm_id, footprint_hash, imagery_id, model_id)
);
CREATE INDEX roof_predictions_area ON roof_predictions (min_lon, max_lon, min_lat, max_lat);
