-- Multi-step training: the validation loss over windows of a job's horizon, beside the
-- one-step loss (NULL for one-step jobs and validation data without such windows).
ALTER TABLE metrics ADD COLUMN val_horizon_loss REAL;
ALTER TABLE jobs ADD COLUMN val_horizon_loss REAL;
