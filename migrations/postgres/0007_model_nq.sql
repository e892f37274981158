-- A model's configuration values nq beside `n`, which is its velocities nv (issue: states as
-- configuration and velocity). NULL for a model stored before: its nq is its n.
ALTER TABLE models ADD COLUMN nq BIGINT;
