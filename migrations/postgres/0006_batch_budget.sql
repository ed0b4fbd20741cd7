-- Classification batches are bounded, as migrations/0011_batch_budget.sql on SQLite: each
-- records the client that asked for it and the bytes it keeps in the store, counted against
-- --classify-store-mb and the client's share of it; finished batches expire
-- (--classify-batch-ttl-s).
ALTER TABLE roof_batches ADD COLUMN client TEXT NOT NULL DEFAULT '';
ALTER TABLE roof_batches ADD COLUMN bytes BIGINT NOT NULL DEFAULT 0;
ALTER TABLE roof_batches ADD COLUMN expired BIGINT NOT NULL DEFAULT 0;
UPDATE roof_batches SET bytes = 512 + 112 * (SELECT COUNT(*) FROM roof_batch_jobs l
    WHERE l.batch_id = roof_batches.id);
CREATE INDEX roof_batches_live ON roof_batches (expired, created_at);
CREATE INDEX roof_batches_client ON roof_batches (client, expired);
