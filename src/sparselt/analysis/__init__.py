"""Sparsity analysis and image metrics (thesis ch. 5 and 7)."""
