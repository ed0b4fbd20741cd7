-- Adaptations of the roof classifier to one imagery source (docs/method.md section 13), as the
-- SQLite table of migrations/0007_roof_adaptations.sql: the tagged buildings of a box are
-- cropped, embedded and a head is fitted on them. The newest head done for an imagery and model
-- is the one in use (after a restart too).
CREATE TABLE roof_adaptations (
    -- 128 random bits, hex: unguessable.
    id          TEXT   PRIMARY KEY,
    created_at  BIGINT NOT NULL,
    updated_at  BIGINT NOT NULL,
    bbox        TEXT   NOT NULL,
    imagery_id  TEXT   NOT NULL,
    -- The model whose embedding the head reads.
    model_id    TEXT   NOT NULL,
    -- running, done, too_few, failed
    state       TEXT   NOT NULL,
    -- Tagged buildings found per class, JSON [flat, gabled, hipped].
    examples    TEXT   NOT NULL,
    -- Buildings cropped so far, and those whose crop failed.
    cropped     BIGINT NOT NULL DEFAULT 0,
    crop_failed BIGINT NOT NULL DEFAULT 0,
    -- The head (JSON, citymesh-roof-head/1) and its id, once fitted.
    head        TEXT,
    head_id     TEXT,
    -- The cross-validated report (JSON), once fitted.
    report      TEXT,
    error       TEXT
);
CREATE INDEX roof_adaptations_in_use ON roof_adaptations (imagery_id, model_id, state, updated_at);
