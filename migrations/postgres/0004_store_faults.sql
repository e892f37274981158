-- Objects are deleted by a collector, outside any transaction: a key whose count reached 0
-- stays until a collector claims it (deleting_by, until deleting_until_ms on the database's
-- clock), deletes the object and then the row. A write of the same bytes during a claim waits
-- for it to end.
ALTER TABLE blob_refs ADD COLUMN deleting_by TEXT;
ALTER TABLE blob_refs ADD COLUMN deleting_until_ms BIGINT;

-- A job's storage failures are counted over time: when the current run of them began (NULL
-- once a checkpoint is stored again), and when the job may be claimed again after one.
ALTER TABLE jobs ADD COLUMN infra_since_ms BIGINT;
ALTER TABLE jobs ADD COLUMN not_before_ms BIGINT;
