-- Models may come from a file instead of a job (POST /v1/models): `job_id` becomes nullable
-- and `origin` says which ('trained' or 'uploaded'). SQLite cannot drop a NOT NULL in place,
-- so the table is rebuilt with its rows (keeping their seq, the listing order).
CREATE TABLE models_new (
    seq        INTEGER PRIMARY KEY AUTOINCREMENT,
    id         TEXT    NOT NULL UNIQUE,
    job_id     TEXT    UNIQUE,
    origin     TEXT    NOT NULL DEFAULT 'trained' CHECK (origin IN ('trained', 'uploaded')),
    name       TEXT    NOT NULL,
    n          INTEGER NOT NULL,
    m          INTEGER NOT NULL,
    dt         REAL    NOT NULL,
    spec       TEXT    NOT NULL,
    report     TEXT    NOT NULL,
    file       BLOB    NOT NULL,
    sha256     TEXT    NOT NULL,
    created_at TEXT    NOT NULL,
    CHECK ((origin = 'trained') = (job_id IS NOT NULL))
);
INSERT INTO models_new (seq, id, job_id, origin, name, n, m, dt, spec, report, file, sha256, created_at)
    SELECT seq, id, job_id, 'trained', name, n, m, dt, spec, report, file, sha256, created_at FROM models;
DROP TABLE models;
ALTER TABLE models_new RENAME TO models;
CREATE INDEX models_uploaded_sha256 ON models (sha256) WHERE origin = 'uploaded';
