"""Importance maps and guided rendering (thesis 6.2, 8.3, 8.4, 9.3)."""

from .importance_map import ConditionalMap, ImportanceMap

__all__ = ["ConditionalMap", "ImportanceMap"]
