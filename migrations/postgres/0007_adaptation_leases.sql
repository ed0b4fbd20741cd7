-- One running adaptation per imagery under a lease, as migrations/0012_adaptation_leases.sql on
-- SQLite.
UPDATE roof_adaptations SET state = 'failed', error = 'interrupted by an upgrade; ask again'
    WHERE state = 'running';
ALTER TABLE roof_adaptations ADD COLUMN owner TEXT;
ALTER TABLE roof_adaptations ADD COLUMN lease_until BIGINT;
CREATE UNIQUE INDEX roof_adaptations_one_running ON roof_adaptations (imagery_id)
    WHERE state = 'running';
