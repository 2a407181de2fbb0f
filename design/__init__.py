"""Optimal leg design and workspace analysis (paper §V)."""
