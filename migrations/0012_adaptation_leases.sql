-- One running adaptation per imagery, enforced by the database (the check and the insert are
-- one statement), under a lease its process extends while it works: a replica that dies leaves
-- an adaptation whose lease runs out, which the next request marks failed. States now also
-- include not_better (fitted, but no better than the shipped head: not in use), cancelled and
-- withdrawn (a head taken out of use).
UPDATE roof_adaptations SET state = 'failed', error = 'interrupted by an upgrade; ask again'
    WHERE state = 'running';
ALTER TABLE roof_adaptations ADD COLUMN owner TEXT;
ALTER TABLE roof_adaptations ADD COLUMN lease_until INTEGER;
CREATE UNIQUE INDEX roof_adaptations_one_running ON roof_adaptations (imagery_id)
    WHERE state = 'running';
