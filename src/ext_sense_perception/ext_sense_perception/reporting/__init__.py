"""``ext-sense report``: the paper's tables and plots, from the training room's protocol."""
