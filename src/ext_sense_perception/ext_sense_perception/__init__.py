"""Contact windows, features, models, training and evaluation, and the windowing and inference nodes."""
