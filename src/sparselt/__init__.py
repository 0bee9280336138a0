"""sparselt: sparse reconstruction of multidimensional light transport signals.

Acquire primary-sample-space signals from scenes with Mitsuba 3
(:func:`acquire_signal`, ``sparselt sample``), load them (:func:`load_signal`)
and render path-traced baselines (``sparselt render``). The thesis this
toolkit implements is "Sparse Reconstruction of Multidimensional Light
Transport Signals".
"""

from .rendering.acquire import AcquisitionConfig, NonFiniteSampleError, acquire_signal
from .rendering.layout import KINDS, path_layout
from .rendering.scenes import get_scene, scene_names
from .signal import IncompleteSignalError, Signal, load_signal

__version__ = "0.1.0"

__all__ = [
    "AcquisitionConfig",
    "IncompleteSignalError",
    "KINDS",
    "NonFiniteSampleError",
    "Signal",
    "acquire_signal",
    "get_scene",
    "load_signal",
    "path_layout",
    "scene_names",
]
