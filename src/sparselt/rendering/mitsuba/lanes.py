"""Random lanes and primary-sample-space vectors: one Dr.Jit lane per sample.

Random numbers are a pure function of ``(seed, item, sample index)``: each
lane seeds a PCG32 generator with a TEA hash of its item (a cell or a pixel)
and sample index, so a signal is identical whatever the chunking. The seed
and the first item of a chunk enter the kernel as opaque values, so one
compiled kernel serves every chunk and every seed. Seeds here are 32-bit:
callers' seeds are folded by :func:`sparselt.rendering.mitsuba.launch.fold_seed`.

References
----------
Thesis 2.1.6 and 3.2.2 (primary sample space). F. Zafar, M. Olano and A.
Curtis, "GPU random numbers via the tiny encryption algorithm", HPG 2010
(TEA). M. E. O'Neill, "PCG: a family of simple fast space-efficient
statistically good algorithms for random number generation" (2014).
"""

from __future__ import annotations


import numpy as np

from ..layout import check_indexable_grid, grid_strides
from .readback import to_device
from .runtime import modules

#: The largest float32 below 1: every coordinate in primary sample space is clamped to ``[0, 1)``.
ONE_MINUS_EPSILON = float(np.float32(1.0) - np.float32(2.0**-24))


def item_lanes(count, spp, seed, *, first=0, stream=0, items=None, order=None, first_sample=None):
    """One lane per sample: ``spp`` samples of each of ``count`` items (cells or pixels) from ``first``.

    With ``first_sample`` the items' sample indices run from it instead of 0
    (an opaque value: one kernel for every offset, 0 included).

    With ``items`` (a ``mi.UInt32`` of ``count`` item numbers) the items are
    those instead of the run ``first, first + 1, ...``. With ``order`` (a
    ``mi.UInt32`` permutation of the ``count * spp`` sample numbers) lane
    ``i`` draws sample ``order[i]``: the same samples in another order.

    Returns ``(item, generator, lane_count)``. Each lane's PCG32 is seeded
    with a TEA hash of (item, sample index, seed), so a sample's random
    numbers are a pure function of those, whatever the batching; ``stream``
    separates estimators that must not share numbers. Sizes and seeds enter
    the kernel as opaque values: one compiled kernel serves every call.
    """
    mi, dr = modules()
    lane_count = int(count) * int(spp)
    index = dr.arange(mi.UInt32, lane_count) if order is None else order
    samples_per_item = dr.opaque(mi.UInt32, int(spp))
    if items is None:
        item = dr.opaque(mi.UInt32, int(first)) + index // samples_per_item
    else:
        item = dr.gather(mi.UInt32, items, index // samples_per_item)
    sample_index = index % samples_per_item
    if first_sample is not None:
        sample_index = sample_index + dr.opaque(mi.UInt32, int(first_sample))
    return item, seeded_generator(item, sample_index, seed, stream), lane_count


def unit_lanes(lane_count, block, block_count, items, first_samples, seed, *, stream=0):
    """Lanes of ``block_count`` blocks of ``block`` consecutive samples each, then of single samples.

    Unit ``u`` (a block, or after the blocks one lane) draws item
    ``items[u]``'s samples from ``first_samples[u]`` (``mi.UInt32``
    tables); lane ``i < block * block_count`` is sample ``i % block`` of
    block ``i // block``, lane ``block * block_count + j`` is unit
    ``block_count + j``. Seeded exactly as :func:`item_lanes` seeds (item,
    sample index); sizes are opaque: one kernel for every layout. Returns
    ``(item, generator)``.
    """
    mi, dr = modules()
    index = dr.arange(mi.UInt32, int(lane_count))
    size = dr.opaque(mi.UInt32, int(block))
    blocked = dr.opaque(mi.UInt32, int(block) * int(block_count))
    in_blocks = index < blocked
    unit = dr.select(in_blocks, index // size, dr.opaque(mi.UInt32, int(block_count)) + index - blocked)
    item = dr.gather(mi.UInt32, items, unit)
    sample_index = dr.gather(mi.UInt32, first_samples, unit) + dr.select(in_blocks, index % size, 0)
    return item, seeded_generator(item, sample_index, seed, stream)


def seeded_generator(item, sample_index, seed, stream):
    """The PCG32 of each lane, seeded with a TEA hash of (item, sample index, 32-bit ``seed``) on ``stream``."""
    mi, dr = modules()
    seed_value = dr.opaque(mi.UInt32, int(seed))
    generator = mi.PCG32()
    generator.seed(mi.sample_tea_64(item, (sample_index << 16) ^ seed_value), mi.UInt64(seed_value) + stream)
    return generator


def explicit_lanes(items, sample_indices, seed, *, stream=0):
    """Lanes for explicit (item, sample index) pairs, seeded exactly as :func:`item_lanes` seeds them."""
    mi, _ = modules()
    item = to_device(mi.UInt32, items, np.uint32)
    sample_index = to_device(mi.UInt32, sample_indices, np.uint32)
    return item, seeded_generator(item, sample_index, seed, stream)


def pss_vector(layout, grid_shape, generator, pixel_x, pixel_y, film_size, *, cell=True):
    """One PSS vector per lane from its PCG32, the image-plane dimensions jittered in film pixel ``(pixel_x, pixel_y)``.

    Returns ``(samples, cell)``: name -> ``mi.Float`` for every dimension of
    ``layout``, and the flat C-order grid cell of each lane (None with
    ``cell=False``: the samples are the same). The random
    numbers are drawn in ``layout.dimensions`` order whatever the pixel: a
    lane seeded like another but given a neighbouring pixel replays its
    numbers there (the gradient-domain shift,
    :func:`sparselt.rendering.mitsuba.gradients.sample_gradients`).

    Raises
    ------
    ValueError
        ``cell`` is asked for on a grid of more cells than a 32-bit index
        counts (:func:`check_indexable_grid`).
    """
    mi, dr = modules()
    film_width, film_height = film_size
    if cell:
        check_indexable_grid(grid_shape)
    strides = grid_strides(grid_shape) if cell else None
    axis_of = {name: position for position, name in enumerate(layout.axes)}
    samples = {}
    flat_cell = mi.UInt32(0) if cell else None
    for name in layout.dimensions:
        uniform = generator.next_float32()
        if name == "x":
            uniform = in_pixel(pixel_x, uniform, film_width)
        elif name == "y":
            uniform = in_pixel(pixel_y, uniform, film_height)
        if cell and name in axis_of:
            position = axis_of[name]
            resolution = dr.opaque(mi.Float, float(grid_shape[position]))
            coordinate = dr.minimum(mi.UInt32(uniform * resolution), mi.UInt32(resolution) - 1)
            flat_cell += coordinate * dr.opaque(mi.UInt32, int(strides[position]))
        samples[name] = uniform
    return samples, flat_cell


def in_pixel(pixel, uniform, size):
    """A coordinate in ``[0, 1)`` jittered by ``uniform`` inside pixel ``pixel`` of ``size`` pixels."""
    mi, dr = modules()
    return dr.minimum((mi.Float(pixel) + uniform) * dr.opaque(mi.Float, 1.0 / size), ONE_MINUS_EPSILON)
