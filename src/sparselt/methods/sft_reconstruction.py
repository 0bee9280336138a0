"""Method ``sft``: the Sparse Fourier Transform of the rendered cell-mean signal (thesis 6.1).

The renderer is the SFT's oracle (:class:`~sparselt.recovery.path_space.CellOracle`):
each lattice point the SFT reads is the mean of ``budget.spp`` jittered path
samples inside its grid cell, and every path sample is counted; the image is
the chapter-4 convolution integration of the recovered spectrum
(:func:`~sparselt.recovery.path_space.lattice_image`).
"""

from __future__ import annotations

import math

import numpy as np

from ..recovery.path_space import sft_path_space
from .base import Method, MethodResult, PhaseTimer
from .registry import register

DEFAULT_ALPHA = 4.0
DEFAULT_SNR = 10.0
THESIS_SPARSITY_FRACTION = 1e-4  # thesis 6.1.1: K = N / 10^4


def sft_options(context):
    """``(K, alpha, snr)`` of a comparison: K defaults to N / 10^4, as the thesis."""
    options = context.options
    size = math.prod(context.grid_shape)
    sparsity = options.get("sparsity") or max(1, round(size * THESIS_SPARSITY_FRACTION))
    alpha = options.get("alpha") or DEFAULT_ALPHA
    snr = DEFAULT_SNR if options.get("sft_snr") is None else options["sft_snr"]
    return int(sparsity), float(alpha), float(snr)


def reconstruct(context, spp, seed):
    """The SFT reconstruction of the context's grid at ``spp`` path samples per lattice point."""
    grid = tuple(context.grid_shape)
    sparsity, alpha, snr = sft_options(context)

    def evaluate(cells):
        return context.scene.sample_cells(context.layout, grid, 0, 0, spp, seed, cells=cells)

    return sft_path_space(evaluate, grid, sparsity, spp, alpha=alpha, snr=snr, seed=seed)


@register
class SparseFourierMethod(Method):
    """Image from the SFT of the rendered signal; ``--spp`` is path samples per lattice point."""

    name = "sft"
    kinds = ("path", "path-indirect", "dof", "indirect")
    description = ("Sparse Fourier Transform of the rendered signal on the rank-1 lattice (thesis 6.1); "
                   "--spp = path samples per lattice point, --sparsity K (default N/10^4), --alpha")
    needs_resolution_multiple = True

    def run(self, context, budget):
        timer = PhaseTimer()
        result = reconstruct(context, budget.spp, budget.seed)
        timer.seconds["sampling"] = result.seconds["sampling"]
        timer.seconds["reconstruction"] = result.seconds["reconstruction"]
        with timer("integration"):
            image = result.image()
            image = np.repeat(np.repeat(image, context.upscale[1], axis=0), context.upscale[0], axis=1)
        sparsity, alpha, snr = sft_options(context)
        width, height = context.grid_shape[:2]
        return MethodResult(
            image=np.ascontiguousarray(image, dtype=np.float32), seconds=timer.seconds,
            path_samples=result.path_samples,
            details={"support_samples": result.support_samples, "magnitude_samples": result.magnitude_samples,
                     "lattice_points": result.cells, "samples_per_point": budget.spp,
                     "samples_per_pixel": result.path_samples / (width * height), "sparsity": sparsity,
                     "alpha": alpha, "snr_db": snr, "nonfinite_samples": result.nonfinite,
                     "stop_reasons": [r.stop_reason for r in result.results],
                     "coefficients": [int(s.indices.size) for s in result.spectra]})
