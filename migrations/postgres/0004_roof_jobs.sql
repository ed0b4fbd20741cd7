-- Roof classification (docs/method.md section 11), as the SQLite tables of migrations/0004,
-- 0005, 0008 and 0009 end up: batches asked for over HTTP or the command line, one job per
-- building and inputs, the batches each job belongs to, and the predictions jobs made. Times are
-- milliseconds since the Unix epoch.
CREATE TABLE roof_batches (
    id          BIGSERIAL PRIMARY KEY,
    created_at  BIGINT    NOT NULL,
    -- west,south,east,north as asked.
    bbox        TEXT      NOT NULL,
    imagery_id  TEXT      NOT NULL,
    model_id    TEXT      NOT NULL,
    -- Counts when the batch was made (JSON: queued, already, skipped by reason).
    counts      TEXT      NOT NULL,
    -- 0 or 1, as on SQLite.
    cancelled   BIGINT    NOT NULL DEFAULT 0,
    -- 128 random bits, hex: the batch's name for clients (ids in sequence would let anyone read
    -- or delete another client's batch).
    token       TEXT      NOT NULL UNIQUE
);

-- A building is classified once per footprint, imagery and model: the unique key. A worker
-- claims jobs under a random claim number and a lease (`FOR UPDATE SKIP LOCKED`, so replicas
-- never take the same job); a job whose lease ran out (its worker died) is claimed again.
CREATE TABLE roof_jobs (
    id             BIGSERIAL PRIMARY KEY,
    batch_id       BIGINT    NOT NULL REFERENCES roof_batches (id),
    osm_id         TEXT      NOT NULL,
    footprint_hash TEXT      NOT NULL,
    imagery_id     TEXT      NOT NULL,
    model_id       TEXT      NOT NULL,
    -- The outer ring, JSON [[lon, lat], ...]: all a worker needs.
    footprint      TEXT      NOT NULL,
    -- queued, running, done, failed, cancelled
    state          TEXT      NOT NULL,
    attempts       BIGINT    NOT NULL DEFAULT 0,
    lease_until    BIGINT,
    error          TEXT,
    updated_at     BIGINT    NOT NULL,
    claim          BIGINT,
    UNIQUE (osm_id, footprint_hash, imagery_id, model_id)
);
CREATE INDEX roof_jobs_claim ON roof_jobs (state, lease_until);
CREATE INDEX roof_jobs_batch ON roof_jobs (batch_id, state);

-- A job belongs to every batch that asked for it, not only to the one that queued it: deleting
-- one batch cancels only the queued jobs no other live batch wants.
CREATE TABLE roof_batch_jobs (
    batch_id BIGINT NOT NULL REFERENCES roof_batches (id),
    job_id   BIGINT NOT NULL REFERENCES roof_jobs (id),
    PRIMARY KEY (batch_id, job_id)
);
CREATE INDEX roof_batch_jobs_job ON roof_batch_jobs (job_id);

CREATE TABLE roof_predictions (
    osm_id         TEXT             NOT NULL,
    footprint_hash TEXT             NOT NULL,
    imagery_id     TEXT             NOT NULL,
    model_id       TEXT             NOT NULL,
    p_flat         DOUBLE PRECISION NOT NULL,
    p_gabled       DOUBLE PRECISION NOT NULL,
    p_hipped       DOUBLE PRECISION NOT NULL,
    footprint      TEXT             NOT NULL,
    min_lon        DOUBLE PRECISION NOT NULL,
    min_lat        DOUBLE PRECISION NOT NULL,
    max_lon        DOUBLE PRECISION NOT NULL,
    max_lat        DOUBLE PRECISION NOT NULL,
    created_at     BIGINT           NOT NULL,
    -- The time the prediction took to make (its share of its worker round: imagery, crop,
    -- inference), milliseconds: /scene/stats sums it as the classification time of a scene.
    work_ms        DOUBLE PRECISION NOT NULL DEFAULT 0,
    PRIMARY KEY (osm_id, footprint_hash, imagery_id, model_id)
);
CREATE INDEX roof_predictions_area ON roof_predictions (min_lon, max_lon, min_lat, max_lat);
