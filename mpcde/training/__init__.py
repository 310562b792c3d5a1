"""The detector's data: rendered datasets, training and held-out scoring."""
