"""Contact windows, features, models, training and evaluation; the windowing and inference nodes."""
