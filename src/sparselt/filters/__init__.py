"""Image and signal filters (thesis 8.2, 8.4): Gaussian, bilateral, cross-bilateral on n-D arrays, and OIDN."""

from .bilateral import bilateral, cross_bilateral, gaussian
from .denoise import oidn_available, oidn_denoise

__all__ = ["bilateral", "cross_bilateral", "gaussian", "oidn_available", "oidn_denoise"]
