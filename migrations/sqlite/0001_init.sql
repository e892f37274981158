-- graybox schema (design.md §4). `seq` columns give a stable, gap-free order for keyset
-- pagination; public ids are strings.

CREATE TABLE datasets (
    seq        INTEGER PRIMARY KEY AUTOINCREMENT,
    id         TEXT    NOT NULL UNIQUE,
    name       TEXT,
    sha256     TEXT    NOT NULL UNIQUE,
    n          INTEGER NOT NULL,
    m          INTEGER NOT NULL,
    dt         REAL    NOT NULL,
    count      INTEGER NOT NULL,
    -- canonical arrays: little-endian f64, q | qdot | u | q_next | qdot_next, row-major
    data       BLOB    NOT NULL,
    created_at TEXT    NOT NULL
);

CREATE TABLE jobs (
    seq                   INTEGER PRIMARY KEY AUTOINCREMENT,
    id                    TEXT    NOT NULL UNIQUE,
    state                 TEXT    NOT NULL
        CHECK (state IN ('queued', 'running', 'succeeded', 'failed', 'cancelled')),
    dataset_id            TEXT    NOT NULL,
    validation_dataset_id TEXT,
    -- the validated, normalized submission (model spec, template, init, training config)
    request               TEXT    NOT NULL,
    epochs                INTEGER NOT NULL,
    epoch                 INTEGER NOT NULL DEFAULT 0,
    checkpoint_epoch      INTEGER NOT NULL DEFAULT 0,
    train_loss            REAL,
    val_loss              REAL,
    best_val_loss         REAL,
    attempt               INTEGER NOT NULL DEFAULT 0,
    lease_owner           TEXT,
    lease_expires_ms      INTEGER,
    heartbeat_ms          INTEGER,
    cancel_requested      INTEGER NOT NULL DEFAULT 0,
    infra_failures        INTEGER NOT NULL DEFAULT 0,
    error                 TEXT,
    model_id              TEXT,
    idempotency_key       TEXT UNIQUE,
    request_sha256        TEXT,
    created_at            TEXT    NOT NULL,
    started_at            TEXT,
    finished_at           TEXT
);

CREATE INDEX jobs_claimable ON jobs (state, seq);

CREATE TABLE metrics (
    job_id     TEXT    NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
    epoch      INTEGER NOT NULL,
    train_loss REAL    NOT NULL,
    val_loss   REAL,
    seconds    REAL    NOT NULL,
    PRIMARY KEY (job_id, epoch)
);

-- The latest committed checkpoint of each job: replaced atomically inside a transaction.
CREATE TABLE checkpoints (
    job_id     TEXT    PRIMARY KEY REFERENCES jobs (id) ON DELETE CASCADE,
    epoch      INTEGER NOT NULL,
    attempt    INTEGER NOT NULL,
    state      BLOB    NOT NULL,
    sha256     TEXT    NOT NULL,
    created_at TEXT    NOT NULL
);

CREATE TABLE models (
    seq        INTEGER PRIMARY KEY AUTOINCREMENT,
    id         TEXT    NOT NULL UNIQUE,
    job_id     TEXT    NOT NULL UNIQUE,
    name       TEXT    NOT NULL,
    n          INTEGER NOT NULL,
    m          INTEGER NOT NULL,
    dt         REAL    NOT NULL,
    spec       TEXT    NOT NULL,
    report     TEXT    NOT NULL,
    file       BLOB    NOT NULL,
    sha256     TEXT    NOT NULL,
    created_at TEXT    NOT NULL
);
