-- Classification batches are bounded (docs/architecture.md, Limits): each records the client that
-- asked for it and the bytes it keeps in the store (its row and one link per building), counted
-- against --classify-store-mb and the client's share of it. Finished batches expire
-- (--classify-batch-ttl-s): their links are deleted, and their row too unless a job still names
-- it as the batch that queued it (then it is kept, small, marked expired).
ALTER TABLE roof_batches ADD COLUMN client TEXT NOT NULL DEFAULT '';
ALTER TABLE roof_batches ADD COLUMN bytes INTEGER NOT NULL DEFAULT 0;
ALTER TABLE roof_batches ADD COLUMN expired INTEGER NOT NULL DEFAULT 0;
UPDATE roof_batches SET bytes = 512 + 112 * (SELECT COUNT(*) FROM roof_batch_jobs l
    WHERE l.batch_id = roof_batches.id);
CREATE INDEX roof_batches_live ON roof_batches (expired, created_at);
CREATE INDEX roof_batches_client ON roof_batches (client, expired);
