"""Sparse recovery algorithms (thesis 2.2, 2.3): CoSaMP, OMP and the Sparse Fourier Transform."""

from .cosamp import cosamp, omp
from .result import RecoveryResult

__all__ = ["RecoveryResult", "cosamp", "omp"]
