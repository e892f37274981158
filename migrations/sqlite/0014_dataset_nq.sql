-- A dataset's configuration values per row nq beside `n`, which is its velocities nv (q and
-- qdot differ in width when a rotation is kept as a unit complex number). NULL for a dataset
-- stored before: its nq is its n.
ALTER TABLE datasets ADD COLUMN nq BIGINT;
