"""Sparse recovery algorithms (thesis 2.2, 2.3): CoSaMP, OMP and the Sparse Fourier Transform."""

from .cosamp import cosamp, omp
from .result import RecoveryResult
from .lattice import sft_lattice
from .sft import SparseFourierTransformResult, sft

__all__ = ["RecoveryResult", "SparseFourierTransformResult", "cosamp", "omp", "sft", "sft_lattice"]
