"""Data files shipped with sparselt."""
