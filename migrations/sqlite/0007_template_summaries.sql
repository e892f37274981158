-- What a list of templates shows of each (coordinates, inputs, periodic, parameters,
-- identifiability) as JSON, computed once when the template is stored, so that a list reads
-- neither the documents nor checks them again. NULL for rows stored before this column; the
-- service computes theirs from the document when it reads them.
ALTER TABLE templates ADD COLUMN summary TEXT;
