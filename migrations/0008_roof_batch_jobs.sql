-- A job belongs to every batch that asked for it, not only to the one that queued it: deleting
-- one batch cancels only the queued jobs no other live batch wants.
CREATE TABLE roof_batch_jobs (
    batch_id INTEGER NOT NULL REFERENCES roof_batches (id),
    job_id   INTEGER NOT NULL REFERENCES roof_jobs (id),
    PRIMARY KEY (batch_id, job_id)
);
CREATE INDEX roof_batch_jobs_job ON roof_batch_jobs (job_id);
INSERT INTO roof_batch_jobs (batch_id, job_id) SELECT batch_id, id FROM roof_jobs;
