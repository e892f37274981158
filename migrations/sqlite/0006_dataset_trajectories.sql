-- The trajectory boundaries of a dataset uploaded in trajectory form: a JSON array of each
-- trajectory's number of transitions, in order. NULL for flat uploads, whose trajectories
-- are the chains of rows where one row's next state is the next row's state exactly.
ALTER TABLE datasets ADD COLUMN trajectories TEXT;
