-- A model's energy report measured on request against a dataset (POST
-- /v1/models/{id}/energy-report): JSON, NULL until asked for.
ALTER TABLE models ADD COLUMN energy TEXT;
