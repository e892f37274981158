-- Large bytes in an object store (--blobs): a row whose bytes live there names their key
-- (`<kind>/<sha256>`) and keeps an empty column; rows without a key keep their bytes inline,
-- as before, and are served as they are.
ALTER TABLE datasets ADD COLUMN blob_key TEXT;
ALTER TABLE checkpoints ADD COLUMN blob_key TEXT;
ALTER TABLE models ADD COLUMN blob_key TEXT;

-- How many rows (or writes about to make one) point at each object: it is deleted when the
-- count reaches 0, under the write lock, so that no new reference races the deletion.
CREATE TABLE blob_refs (
    key  TEXT    PRIMARY KEY,
    refs BIGINT NOT NULL
);
