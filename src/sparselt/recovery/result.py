"""The result record every recovery algorithm returns: CoSaMP, the SFT, the screened Poisson solves and the SFT of
a rendered signal (path space), one frozen dataclass with the seconds of each phase."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..fourier.sparse import SparseFourier


@dataclass(frozen=True)
class RecoveryResult:
    """What a recovery algorithm found, and what it cost.

    Attributes
    ----------
    estimate : SparseFourier, ndarray or tuple
        What was recovered: the coefficients for CoSaMP and the SFT
        (``estimate.to_signal()`` is the grid signal), the image for the
        Poisson solves, one spectrum per RGB channel for the path-space SFT.
    residual_history : tuple of float
        Relative residual ``||y - A x|| / ||y||`` after each iteration (the
        L1 Poisson solve: the image's relative change per iteration).
    iterations : int
        Iterations run.
    samples : int
        Samples (measurements) the algorithm read.
    seconds : dict
        Wall seconds per phase (e.g. proxy, select, least_squares, prune, residual).
    stop_reason : str
        'converged', 'stagnated', 'max_iterations', 'sparsity_reached' or
        'exact' (a direct solve).
    transforms : int
        Number of full FFTs performed (the cost floor of matrix-free recovery).
    """

    estimate: SparseFourier
    residual_history: tuple = ()
    iterations: int = 0
    samples: int = 0
    seconds: dict = field(default_factory=dict)
    stop_reason: str = ""
    transforms: int = 0

    @property
    def support(self):
        """Flat spectrum indices of the estimate."""
        return self.estimate.indices

    @property
    def total_seconds(self):
        return float(sum(self.seconds.values()))

    @property
    def relative_residual(self):
        return float(self.residual_history[-1]) if self.residual_history else float("nan")

    def relative_error(self, truth):
        """``||x_hat - x|| / ||x||`` against a reference grid signal."""
        truth = np.asarray(truth)
        return float(np.linalg.norm(self.estimate.to_signal() - truth) / np.linalg.norm(truth))
