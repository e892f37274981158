-- Times a job's worker died holding it (its lease expired and the job was reclaimed); at
-- `--max-attempts` the job fails instead of running again. Releases on SIGTERM do not count.
ALTER TABLE jobs ADD COLUMN worker_deaths INTEGER NOT NULL DEFAULT 0;
