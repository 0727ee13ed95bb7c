"""Evaluation: the metrics of the paper, their directions, the per-material tables."""
