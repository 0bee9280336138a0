"""The signal's estimator: the mean of jittered path samples in each cell of a primary-sample-space grid.

References
----------
Thesis 3.2.2 (a rendered signal: the integrand averaged over each grid cell)
and 6.1 (the Sparse Fourier Transform reads single cells through it).
"""

from __future__ import annotations

import numpy as np

from ..layout import grid_strides
from .integrand import path_contribution, zero_nonfinite
from .lanes import ONE_MINUS_EPSILON, item_lanes
from .launch import launch
from .readback import rgb_array, to_device
from .runtime import modules


def sample_cells(scene, layout, grid_shape, first_cell, cell_count, spp, seed, *, cells=None):
    """Mean of ``spp`` jittered samples in each of a run of grid cells.

    Parameters
    ----------
    scene : MitsubaScene
    layout : PathLayout
        Meaning of every PSS dimension; ``layout.axes`` are gridded.
    grid_shape : tuple of int
        Resolution of each axis, in ``layout.axes`` order.
    first_cell, cell_count : int
        The cells ``first_cell .. first_cell + cell_count - 1`` in C order.
    spp : int
        Jittered samples per cell.
    seed : int
        Any non-negative integer (:func:`~sparselt.rendering.mitsuba.launch.fold_seed`).
    cells : array_like of int, optional
        Sample these cells (flat C-order indices, any order, repeats
        allowed) instead of the run; ``first_cell`` and ``cell_count``
        are then ignored. A cell's samples are the same either way: the
        Sparse Fourier Transform's oracle reads single cells through it.

    Returns
    -------
    means : ndarray, shape (cell_count, 3), float32
        Per-cell mean RGB over the finite samples (non-finite ones count as 0).
    nonfinite : ndarray, shape (cell_count,), int64
        Number of samples in each cell whose value was NaN or infinite.
    """
    if cells is not None:
        cells = np.ascontiguousarray(cells, dtype=np.uint32)
        cell_count = int(cells.size)

    def work(folded_seed):
        mi, dr = modules()
        items = None if cells is None else to_device(mi.UInt32, cells, np.uint32)
        cell, generator, _ = item_lanes(cell_count, spp, folded_seed, first=first_cell, items=items)
        strides = grid_strides(grid_shape)
        axis_of = {name: position for position, name in enumerate(layout.axes)}
        samples = {}
        for name in layout.dimensions:
            uniform = generator.next_float32()
            if name in axis_of:
                position = axis_of[name]
                resolution = int(grid_shape[position])
                coordinate = (cell // int(strides[position])) % resolution
                uniform = dr.minimum((mi.Float(coordinate) + uniform) * (1.0 / resolution), ONE_MINUS_EPSILON)
            samples[name] = uniform

        value, finite = zero_nonfinite(path_contribution(scene, layout, samples))
        invalid = dr.select(finite, mi.UInt32(0), mi.UInt32(1))
        # One kernel for all outputs: reducing unevaluated channels one by one
        # would trace and run the whole path kernel once per channel.
        dr.eval(value, invalid)
        scale = 1.0 / spp
        sums = [dr.block_sum(channel, spp) * scale for channel in (value.x, value.y, value.z)]
        bad = dr.block_sum(invalid, spp)
        dr.eval(sums, bad)
        return rgb_array(sums), np.asarray(bad, dtype=np.int64)

    return launch(work, seed, path_samples=int(cell_count) * int(spp))
