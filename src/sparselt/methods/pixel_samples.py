"""Path samples drawn per output pixel.

:func:`draw_pixel_samples` is the acquisition of thesis 8.1.1: ``spp`` path
samples per pixel, each at a uniformly random cell of the pixel's non-image
axes, jittered inside it (the sampler's layout and random streams). The
CoSaMP methods and ``samples-mean`` draw exactly the same samples for the same
budget, so ``samples-mean`` shows what the reconstruction itself adds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .. import cell_statistics, kernels
from ..images import luminance

LANES_PER_LAUNCH = 1 << 22


@dataclass(frozen=True)
class PixelSamples:
    """The samples of one budget.

    Attributes
    ----------
    values : ndarray, shape (pixels * spp, 3), float32
        Path contributions, pixel-major in row-major pixel order.
    cells : ndarray, shape (pixels * spp,), int64, or None
        Flat grid cell of each sample; None when drawn without them
        (:func:`draw_pixel_samples` ``cells=False``).
    spp : int
    resolution : tuple of int
        Output ``(width, height)``.
    nonfinite : int
        Samples that were NaN or infinite (replaced by 0).
    auxiliary : dict
        Per-sample quantities drawn in the same kernel
        (:data:`~sparselt.rendering.mitsuba.AUXILIARY_QUANTITIES`), one
        row per sample in the order of ``values``; empty unless requested.
    """

    values: np.ndarray
    cells: np.ndarray | None
    spp: int
    resolution: tuple
    nonfinite: int
    auxiliary: dict = field(default_factory=dict)

    def pixel_means(self):
        """Per-pixel mean RGB, shape (height, width, 3), float32 (accumulated in float64)."""
        width, height = self.resolution
        return self.values.reshape(height, width, self.spp, 3).mean(axis=2, dtype=np.float64).astype(np.float32)

    def fold(self, index, folds=2):
        """The samples whose index within their pixel is ``index`` modulo ``folds`` (a cross-fitting fold)."""
        def take(array):
            per_pixel = array.reshape((-1, self.spp) + array.shape[1:])[:, index::folds]
            return np.ascontiguousarray(per_pixel).reshape((-1,) + array.shape[1:])

        return PixelSamples(values=take(self.values), cells=None if self.cells is None else take(self.cells),
                            spp=len(range(index, self.spp, folds)), resolution=self.resolution, nonfinite=0,
                            auxiliary={name: take(array) for name, array in self.auxiliary.items()})

    def pixel_means_of(self, per_sample):
        """Per-pixel mean of any per-sample quantity, shape (height, width) (or (height, width, channels))."""
        width, height = self.resolution
        per_sample = np.asarray(per_sample)
        return per_sample.reshape((height, width, self.spp) + per_sample.shape[1:]).mean(axis=2, dtype=np.float64)

    def per_pixel(self, per_sample):
        """A per-sample quantity as ``(height, width, spp, ...)`` (a view)."""
        width, height = self.resolution
        per_sample = np.asarray(per_sample)
        return per_sample.reshape((height, width, self.spp) + per_sample.shape[1:])


def draw_pixel_samples(context, budget, *, resolution=None, auxiliary=(), cells=True):
    """Draw ``budget.spp`` samples per pixel in launches of about 4M lanes.

    ``resolution`` (default the comparison's output resolution) is the pixel
    grid: a pilot pass for an importance map draws per map cell instead.
    ``auxiliary`` names per-sample quantities drawn in the same kernels
    (:data:`~sparselt.rendering.mitsuba.AUXILIARY_QUANTITIES`). ``cells``:
    whether to compute each sample's grid cell (the methods that bin samples
    into the signal grid); without them the samples are the same, and a
    grid too large to index (a deep ``path`` layout's default) is no obstacle.
    A method's warm-up draws as its run does (the kernels differ).
    """
    width, height = resolution or context.resolution
    pixels = width * height
    per_launch = max(1, LANES_PER_LAUNCH // budget.spp)
    values = np.empty((pixels * budget.spp, 3), dtype=np.float32)
    flat_cells = np.empty(pixels * budget.spp, dtype=np.int64) if cells else None
    nonfinite = 0
    recorded = {}
    for first in range(0, pixels, per_launch):
        count = min(per_launch, pixels - first)
        launch = context.scene.sample_pixels(
            context.layout, context.grid_shape, budget.spp, budget.seed, first_pixel=first, pixel_count=count,
            resolution=(width, height), cells=cells, **({"auxiliary": tuple(auxiliary)} if auxiliary else {}))
        launch_values, launch_cells, bad = launch[:3]
        rows = slice(first * budget.spp, (first + count) * budget.spp)
        values[rows] = launch_values
        if cells:
            flat_cells[rows] = launch_cells
        nonfinite += bad
        for name, array in (launch[3].items() if auxiliary else ()):
            if name not in recorded:
                recorded[name] = np.empty((pixels * budget.spp,) + array.shape[1:], dtype=array.dtype)
            recorded[name][rows] = array
    return PixelSamples(values=values, cells=flat_cells, spp=budget.spp, resolution=(width, height),
                        nonfinite=nonfinite, auxiliary=recorded)


def sample_mean_image(context, budget, timer, *, cells=False):
    """Draw the budget's samples ('sampling'; their grid cells only with ``cells``) and average them per pixel
    ('integration'): the path-traced image."""
    with timer("sampling"):
        samples = draw_pixel_samples(context, budget, cells=cells)
    with timer("integration"):
        image = samples.pixel_means()
    return samples, image


def cell_means(samples, size, grid_shape=None):
    """Luminance measurements of the sampled cells (thesis 8.1.1: a cell that receives samples is measured by their mean).

    The mean of each cell's luminances, :func:`sparselt.cell_statistics.cell_means`.
    With the signal's ``grid_shape`` (whose image axes divide the samples'
    resolution), the sums run per image-cell block on every core
    (:func:`~sparselt.kernels.pixel_block_cell_sums`): the same numbers,
    without two grid-size arrays.

    Returns
    -------
    cells : ndarray of int64, sorted
        Cells that received at least one sample.
    means : ndarray of float64
        Mean luminance of each of those cells.
    counts : ndarray of int64
        Samples in each.
    """
    weights = luminance(samples.values)
    if grid_shape is not None and math.prod(grid_shape) == size and len(grid_shape) >= 2:
        width, height = samples.resolution
        if width % grid_shape[0] == 0 and height % grid_shape[1] == 0:
            cells, sums, counts = kernels.pixel_block_cell_sums(samples.cells, weights, samples.spp,
                                                                samples.resolution, tuple(int(v) for v in grid_shape))
            return cells, sums / counts, counts
    return cell_statistics.cell_means(samples.cells, weights, size)
