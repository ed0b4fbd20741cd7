-- The time a prediction took to make (its share of its worker round: imagery, crop, inference),
-- milliseconds: /scene/stats sums it as the classification time of a scene's roofs.
ALTER TABLE roof_predictions ADD COLUMN work_ms REAL NOT NULL DEFAULT 0;
