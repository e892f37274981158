-- Templates as a resource (POST /v1/templates): a user's mechanism stored once, named by
-- jobs by id. `document` is the canonical JSON (sorted keys, no spaces) whose sha256 makes
-- the same document uploaded twice one template.
CREATE TABLE templates (
    seq        INTEGER PRIMARY KEY AUTOINCREMENT,
    id         TEXT    NOT NULL UNIQUE,
    kind       TEXT    NOT NULL,
    name       TEXT    NOT NULL,
    n          INTEGER NOT NULL,
    m          INTEGER NOT NULL,
    document   TEXT    NOT NULL,
    sha256     TEXT    NOT NULL UNIQUE,
    created_at TEXT    NOT NULL
);
-- The stored template a job was submitted with (its spec embeds the whole template, so a
-- finished job needs no row here; a queued or running one keeps its template from deletion).
ALTER TABLE jobs ADD COLUMN template_id TEXT;
CREATE INDEX jobs_template_id ON jobs (template_id) WHERE template_id IS NOT NULL;
