"""Linear operators (thesis 2.2): matrix-free sampling and representation operators, in PyLops terms."""

from .base import AdjointOperator, LinearOperator, SupportRestricted, dottest
from .partial_fourier import PartialFourier, mean_per_cell

__all__ = ["AdjointOperator", "LinearOperator", "PartialFourier", "SupportRestricted", "dottest", "mean_per_cell"]
