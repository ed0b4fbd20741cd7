-- A batch is named to clients by a 128-bit random token, not by its row id: ids in sequence let
-- anyone read or delete another client's batch.
ALTER TABLE roof_batches ADD COLUMN token TEXT;
UPDATE roof_batches SET token = lower(hex(randomblob(16))) WHERE token IS NULL;
CREATE UNIQUE INDEX roof_batches_token ON roof_batches (token);

-- A claim is named by a random number, not by its lease's end: a worker extends its lease while
-- it works, and every state change checks the claim is still the worker's.
ALTER TABLE roof_jobs ADD COLUMN claim INTEGER;
