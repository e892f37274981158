-- Ensembles: the members' standard deviation of each epoch's losses beside their mean
-- (NULL for a single model).
ALTER TABLE metrics ADD COLUMN train_loss_std DOUBLE PRECISION;
ALTER TABLE metrics ADD COLUMN val_loss_std DOUBLE PRECISION;
