-- Warnings a person should read (never blocking): a dataset's sanity checks at upload, a
-- job's training checks when it finishes. JSON arrays of {code, field?, message}.
ALTER TABLE datasets ADD COLUMN warnings TEXT NOT NULL DEFAULT '[]';
ALTER TABLE jobs ADD COLUMN warnings TEXT NOT NULL DEFAULT '[]';
