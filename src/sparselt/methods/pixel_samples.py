"""Path samples drawn per output pixel.

:func:`draw_pixel_samples` is the acquisition of thesis 8.1.1: ``spp`` path
samples per pixel, each at a uniformly random cell of the pixel's non-image
axes, jittered inside it (the sampler's layout and random streams). The
CoSaMP methods and ``samples-mean`` draw exactly the same samples for the same
budget, so ``samples-mean`` shows what the reconstruction itself adds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..images import luminance

LANES_PER_LAUNCH = 1 << 22


@dataclass(frozen=True)
class PixelSamples:
    """The samples of one budget.

    Attributes
    ----------
    values : ndarray, shape (pixels * spp, 3), float32
        Path contributions, pixel-major in row-major pixel order.
    cells : ndarray, shape (pixels * spp,), int64
        Flat grid cell of each sample.
    spp : int
    resolution : tuple of int
        Output ``(width, height)``.
    nonfinite : int
        Samples that were NaN or infinite (replaced by 0).
    """

    values: np.ndarray
    cells: np.ndarray
    spp: int
    resolution: tuple
    nonfinite: int

    def pixel_means(self):
        """Per-pixel mean RGB, shape (height, width, 3), float32 (accumulated in float64)."""
        width, height = self.resolution
        return self.values.reshape(height, width, self.spp, 3).mean(axis=2, dtype=np.float64).astype(np.float32)

    def fold(self, index, folds=2):
        """The samples whose index within their pixel is ``index`` modulo ``folds`` (a cross-fitting fold)."""
        values = self.values.reshape(-1, self.spp, 3)[:, index::folds]
        cells = self.cells.reshape(-1, self.spp)[:, index::folds]
        return PixelSamples(values=np.ascontiguousarray(values).reshape(-1, 3),
                            cells=np.ascontiguousarray(cells).reshape(-1), spp=values.shape[1],
                            resolution=self.resolution, nonfinite=0)

    def pixel_means_of(self, per_sample):
        """Per-pixel mean of any per-sample quantity, shape (height, width)."""
        width, height = self.resolution
        return np.asarray(per_sample, dtype=np.float64).reshape(height, width, self.spp).mean(axis=2)


def draw_pixel_samples(context, budget, *, resolution=None):
    """Draw ``budget.spp`` samples per pixel in launches of about 4M lanes.

    ``resolution`` (default the comparison's output resolution) is the pixel
    grid: a pilot pass for an importance map draws per map cell instead.
    """
    width, height = resolution or context.resolution
    pixels = width * height
    per_launch = max(1, LANES_PER_LAUNCH // budget.spp)
    values = np.empty((pixels * budget.spp, 3), dtype=np.float32)
    cells = np.empty(pixels * budget.spp, dtype=np.int64)
    nonfinite = 0
    for first in range(0, pixels, per_launch):
        count = min(per_launch, pixels - first)
        launch_values, launch_cells, bad = context.scene.sample_pixels(
            context.layout, context.grid_shape, budget.spp, budget.seed, first_pixel=first, pixel_count=count,
            resolution=(width, height))
        values[first * budget.spp:(first + count) * budget.spp] = launch_values
        cells[first * budget.spp:(first + count) * budget.spp] = launch_cells
        nonfinite += bad
    return PixelSamples(values=values, cells=cells, spp=budget.spp, resolution=(width, height), nonfinite=nonfinite)


def sample_mean_image(context, budget, timer):
    """Draw the budget's samples ('sampling') and average them per pixel ('integration'): the path-traced image."""
    with timer("sampling"):
        samples = draw_pixel_samples(context, budget)
    with timer("integration"):
        image = samples.pixel_means()
    return samples, image


def cell_means(samples, size):
    """Luminance measurements of the sampled cells (thesis 8.1.1: a cell that receives samples is measured by their mean).

    Returns
    -------
    cells : ndarray of int64, sorted
        Cells that received at least one sample.
    means : ndarray of float64
        Mean luminance of each of those cells.
    counts : ndarray of int64
        Samples in each.
    """
    counts = np.bincount(samples.cells, minlength=size)
    sums = np.bincount(samples.cells, weights=luminance(samples.values), minlength=size)
    cells = np.flatnonzero(counts)
    return cells, sums[cells] / counts[cells], counts[cells]
