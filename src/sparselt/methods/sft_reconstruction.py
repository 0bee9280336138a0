"""Method ``sft``: the Sparse Fourier Transform of the rendered cell-mean signal (thesis 6.1).

The renderer is the SFT's oracle (:class:`~sparselt.recovery.path_space.CellOracle`):
each lattice point the SFT reads is the mean of ``budget.spp`` jittered path
samples inside its grid cell, and every path sample is counted; the image is
the chapter-4 convolution integration of the recovered spectrum
(:func:`~sparselt.recovery.path_space.lattice_image`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..recovery.path_space import sft_path_space
from .base import Method, MethodResult
from .options import MethodOptions, option
from .preconditions import GridMemory
from .registry import register

DEFAULT_ALPHA = 4.0
DEFAULT_SNR = 10.0
THESIS_SPARSITY_FRACTION = 1e-4  # thesis 6.1.1: K = N / 10^4


def default_sparsity(grid_shape):
    """``K = N / 10^4`` (thesis 6.1.1), at least 1."""
    return max(1, round(math.prod(grid_shape) * THESIS_SPARSITY_FRACTION))


def _half_the_grid(grid_shape):
    return max(1, math.prod(grid_shape) // 2)


@dataclass(frozen=True)
class SftOptions(MethodOptions):
    """The Sparse Fourier Transform's options, shared by ``sft`` and ``guided-sft`` (thesis 6.1, 6.2)."""

    sparsity: int | None = option(None, derive=default_sparsity, default_text="N/10^4", minimum=1,
                                  maximum=_half_the_grid, maximum_text="N/2", section="6.1.1",
                                  help="K, the Fourier coefficients the SFT recovers")
    alpha: float = option(DEFAULT_ALPHA, minimum=1.0, section="2.3, 6.1.1",
                          help="buckets per coefficient, B = alpha K (the thesis's Table 6.1: 4, 16, 32)")
    snr: float = option(DEFAULT_SNR, section="2.3",
                        help="signal-to-noise ratio in dB the SFT assumes (sets its hash and repetition counts)")


def reconstruct(context, spp, seed, options):
    """The SFT reconstruction of the context's grid at ``spp`` path samples per lattice point.

    ``options`` has ``sparsity``, ``alpha`` and ``snr`` (an :class:`SftOptions`
    or one derived from it).
    """
    grid = tuple(context.grid_shape)

    def evaluate(cells):
        return context.scene.sample_cells(context.layout, grid, 0, 0, spp, seed, cells=cells)

    return sft_path_space(evaluate, grid, int(options.sparsity), spp, alpha=float(options.alpha),
                          snr=float(options.snr), seed=seed)


@register
class SparseFourierMethod(Method):
    """Image from the SFT of the rendered signal; ``--spp`` is path samples per lattice point."""

    name = "sft"
    family = "sft"
    thesis_procedure = True
    Options = SftOptions
    kinds = ("path", "path-indirect", "dof", "indirect")
    description = ("Sparse Fourier Transform of the rendered signal on the rank-1 lattice (thesis 6.1); "
                   "--spp = path samples per lattice point, K = N/10^4 by default")
    needs_resolution_multiple = True
    #: Peak memory beyond PT's per grid cell: 29 and 28 bytes on cornell-box's path grid (16x16 and 32x32 image cells
    #: of 4^8), 44 on dof-sculptures' 64x64x32x32.
    requires = (GridMemory(56.0),)

    def run(self, context, budget, timer):
        options = self.options
        result = reconstruct(context, budget.spp, budget.seed, options)
        timer.seconds["sampling"] += result.seconds["sampling"]
        timer.seconds["reconstruction"] += result.seconds["reconstruction"]
        with timer("integration"):
            image = result.image()
            image = np.repeat(np.repeat(image, context.upscale[1], axis=0), context.upscale[0], axis=1)
        width, height = context.grid_shape[:2]
        return MethodResult(
            image=np.ascontiguousarray(image, dtype=np.float32), path_samples=result.path_samples,
            details={"support_samples": result.support_samples, "magnitude_samples": result.magnitude_samples,
                     "lattice_points": result.cells, "samples_per_point": budget.spp,
                     "samples_per_pixel": result.path_samples / (width * height), "sparsity": options.sparsity,
                     "alpha": options.alpha, "snr_db": options.snr, "nonfinite_samples": result.nonfinite,
                     "stop_reasons": [r.stop_reason for r in result.results],
                     "coefficients": [int(s.indices.size) for s in result.spectra]})
