"""Path samples per film pixel, each at a uniformly random point of the pixel's primary-sample-space box.

References
----------
Thesis 8.1.1 (``spp`` path samples per pixel at random cells).
"""

from __future__ import annotations

import numpy as np

from .integrand import AUXILIARY_QUANTITIES, path_contribution, zero_nonfinite
from .lanes import explicit_lanes, item_lanes, pss_vector, unit_lanes
from .launch import launch
from .readback import count_false, rgb_array, to_numpy
from .runtime import modules


def sample_pixels(scene, layout, grid_shape, spp, seed, first_pixel=0, pixel_count=None, resolution=None,
                  auxiliary=(), lanes=None, cells=True):
    """``spp`` path samples per film pixel, each at a uniformly random point of the pixel's PSS box.

    The image-plane dimensions are jittered inside the film pixel; every
    other dimension (the signal's non-image axes included) is uniform on
    ``[0, 1)``, so the grid cell a sample falls in is uniformly random among
    the pixel's cells and the sample is jittered inside it (thesis 8.1.1).
    Random numbers come from the same TEA-seeded PCG32 streams as
    :func:`~sparselt.rendering.mitsuba.cells.sample_cells`, keyed by (seed,
    pixel, sample index).

    Parameters
    ----------
    scene : MitsubaScene
    layout : PathLayout
        Meaning of every PSS dimension; ``layout.axes`` are gridded.
    grid_shape : tuple of int
        Signal grid, in ``layout.axes`` order. Its image axes must divide
        the film resolution.
    spp : int
        Samples per pixel.
    seed : int
        Any non-negative integer (:func:`~sparselt.rendering.mitsuba.launch.fold_seed`).
    first_pixel, pixel_count : int, optional
        Film pixels ``first_pixel ..`` in row-major order (row ``y``);
        default every pixel.
    resolution : tuple of int, optional
        ``(width, height)`` of the pixel grid the samples are drawn per
        (default the film's): a pilot pass draws per cell of a coarser map.
    auxiliary : tuple of str, optional
        Names of :data:`~sparselt.rendering.mitsuba.integrand.AUXILIARY_QUANTITIES`
        to return as well.
    lanes : tuple of two int arrays, optional
        ``(pixels, sample_indices)``: draw exactly these samples (any
        number per pixel: an adaptive allocation) instead of ``spp`` per
        pixel of the run; ``spp``, ``first_pixel`` and ``pixel_count``
        are then ignored. Sample ``i`` of pixel ``p`` is the same sample
        either way.
    cells : bool, optional
        Whether to compute each sample's grid cell (False: ``cells`` is
        None, the samples are the same). A grid of 2**32 cells or more
        cannot be indexed (:func:`~sparselt.rendering.layout.check_indexable_grid`).

    Returns
    -------
    values : ndarray, shape (pixel_count * spp, 3), float32
        Path contributions, pixel-major (the ``spp`` samples of a pixel are
        consecutive); NaN or infinite ones are replaced by 0.
    cells : ndarray, shape (pixel_count * spp,), int64, or None
        Flat C-order grid cell of each sample (None with ``cells=False``).
    nonfinite : int
        Number of samples that were NaN or infinite.
    auxiliary : dict, only when ``auxiliary`` names quantities
        Each requested name -> a numpy array with one row per sample,
        computed in the same kernel.
    """
    unknown = sorted(set(auxiliary) - set(AUXILIARY_QUANTITIES))
    if unknown:
        raise ValueError(f"unknown auxiliary quantities {unknown}; choose from {', '.join(AUXILIARY_QUANTITIES)}")
    if any(name.startswith("lens_") for name in auxiliary) and not layout.thin_lens:
        raise ValueError("lens coordinates need a thin-lens camera (give --aperture)")
    film_width, film_height = (scene.width, scene.height) if resolution is None else (int(v) for v in resolution)
    pixel_count = film_width * film_height - int(first_pixel) if pixel_count is None else int(pixel_count)
    explicit = lanes

    def work(folded_seed):
        _, dr = modules()
        _, samples, cell = pixel_lanes(layout, grid_shape, spp, folded_seed, first_pixel, pixel_count,
                                       (film_width, film_height), explicit, cell=cells)
        recorded = {} if auxiliary else None
        value, finite = zero_nonfinite(path_contribution(scene, layout, samples, recorded))
        extra = [recorded[name] for name in auxiliary]
        dr.eval(value, finite, *extra, *([cell] if cells else []))
        result = (rgb_array((value.x, value.y, value.z)), np.asarray(cell, dtype=np.int64) if cells else None,
                  count_false(finite))
        if not auxiliary:
            return result
        return result + ({name: to_numpy(recorded[name]) for name in auxiliary},)

    drawn = pixel_count * int(spp) if explicit is None else int(np.size(explicit[0]))
    return launch(work, seed, path_samples=drawn)


def pixel_lanes(layout, grid_shape, spp, seed, first_pixel, pixel_count, film_size, explicit=None, *, cell=True,
                first_sample=None, units=None):
    """The PSS vectors of pixel samples (see :func:`sample_pixels`): ``(pixel, samples, cell)`` per lane.

    ``explicit``, ``(pixels, sample_indices)``, draws exactly those samples
    instead of ``spp`` per pixel of the run; ``units``, the arguments of
    :func:`~sparselt.rendering.mitsuba.lanes.unit_lanes` but the seed, draws
    blocks and single samples of listed pixels; ``seed`` is the 32-bit
    seed; ``cell=False``: no grid cell (None); ``first_sample``: the run's
    sample indices start there (:func:`~sparselt.rendering.mitsuba.lanes.item_lanes`).
    """
    mi, dr = modules()
    if units is not None:
        pixel, generator = unit_lanes(*units, seed)
    elif explicit is None:
        pixel, generator, _ = item_lanes(pixel_count, spp, seed, first=first_pixel, first_sample=first_sample)
    else:
        pixel, generator = explicit_lanes(explicit[0], explicit[1], seed)
    width = dr.opaque(mi.UInt32, film_size[0])
    samples, cell = pss_vector(layout, grid_shape, generator, pixel % width, pixel // width, film_size, cell=cell)
    return pixel, samples, cell
