"""Linear operators (thesis 2.2): matrix-free sampling and representation operators."""

from .base import LinearOperator, dot_test
from .partial_fourier import PartialFourier, mean_per_cell

__all__ = ["LinearOperator", "PartialFourier", "dot_test", "mean_per_cell"]
