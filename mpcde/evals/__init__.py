"""Evaluations and comparisons: compare, eval-tracking, eval-dmpc, eval-mlr, explain, bench, and their tables."""
