"""sparselt: sparse reconstruction of multidimensional light transport signals.

Acquire primary-sample-space signals from scenes with Mitsuba 3
(:func:`acquire_signal`, ``sparselt sample``), load them (:func:`load_signal`)
and render path-traced baselines (``sparselt render``). The thesis this
toolkit implements is "Sparse Reconstruction of Multidimensional Light
Transport Signals".
"""

import os as _os

# numba's OpenMP threads spin after each parallel loop and take the cores from the FFT threads that run next
# (issue 24: CoSaMP on 64x64x16x16 47% slower with spinning threads); they sleep instead unless told otherwise.
# Set before any OpenMP runtime loads, so it holds for every numba kernel of the process.
_os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

from .analysis.metrics import (  # noqa: E402 (after the OpenMP setting)
    peak_signal_to_noise_ratio,
    relative_mean_squared_error,
    root_mean_squared_error,
    structural_similarity,
)
from .analysis.sparsity import gini_index
from .fourier.integration import integrate
from .fourier.sparse import SparseFourier
from .operators import PartialFourier
from .recovery import RecoveryResult, cosamp, omp, sft, sft_lattice
from .rendering.acquire import AcquisitionConfig, NonFiniteSampleError, acquire_signal
from .rendering.layout import KINDS, path_layout
from .rendering.scenes import get_scene, scene_names
from .results import load_comparison, load_summary
from .signal import IncompleteSignalError, Signal, load_signal

__version__ = "0.1.0"

#: Short name of :func:`structural_similarity` (thesis 5.2).
ssim = structural_similarity

__all__ = [
    "AcquisitionConfig",
    "PartialFourier",
    "RecoveryResult",
    "SparseFourier",
    "cosamp",
    "gini_index",
    "integrate",
    "omp",
    "peak_signal_to_noise_ratio",
    "relative_mean_squared_error",
    "root_mean_squared_error",
    "ssim",
    "structural_similarity",
    "IncompleteSignalError",
    "KINDS",
    "NonFiniteSampleError",
    "Signal",
    "acquire_signal",
    "get_scene",
    "load_comparison",
    "load_summary",
    "load_signal",
    "path_layout",
    "scene_names",
    "sft",
    "sft_lattice",
]
