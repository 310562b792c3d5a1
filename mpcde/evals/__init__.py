"""Evaluations and comparisons: compare, eval-tracking, eval-dmpc, eval-mlr, bench, and their tables."""
