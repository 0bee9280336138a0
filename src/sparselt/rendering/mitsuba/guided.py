"""Renders with primary samples drawn from a piecewise-constant importance map, warped inside the kernel.

Also the kind's own path-tracing estimator (:func:`render_estimator`): the
same kernel without a map.

References
----------
Thesis 6.2.1 (importance maps over primary sample space) and 8.3 (guided
sampling of the comparison's methods).
"""

from __future__ import annotations

import numpy as np

from ... import kernels
from .integrand import path_contribution, zero_nonfinite
from .lanes import ONE_MINUS_EPSILON, in_pixel, item_lanes
from .launch import launch
from .readback import count_false, rgb_array, to_device
from .runtime import initialize, modules

GUIDED_STREAM = 0x9E37  # PCG32 stream of guided renders, apart from the signal and pixel-sample streams


def render_estimator(scene, layout, spp, seed):
    """Path tracing of the kind's own estimator (every PSS dimension uniform), ``spp`` per pixel, in one kernel.

    The same kernel as :func:`render_guided` without a map: the fair
    path-tracing baseline for kinds Mitsuba's ``path`` cannot render alone
    (``indirect``). Returns ``(image, nonfinite)``.
    """
    return render_guided(scene, layout, None, None, None, spp, seed, mode="per-pixel")


def render_guided(scene, layout, map_shape, tables, densities, spp, seed, *, mode):
    """Render the film with primary samples drawn from a piecewise-constant importance map (thesis 6.2.1, 8.3).

    The map's axes are ``layout.axes`` (the signal kind's axes) with
    resolution ``map_shape``; every other PSS dimension stays uniform. The
    guided vector is warped inside the kernel, one axis at a time, by a
    binary search in the conditional CDF of that axis given the cells
    already chosen (:meth:`ImportanceMap.level_tables`); the remainder of
    the uniform is the jitter inside the cell. Each sample contributes
    ``f(u) / p(u)``.

    Parameters
    ----------
    scene : MitsubaScene
    layout : PathLayout
    map_shape : tuple of int
        Map resolution per axis; its image axes divide the film resolution.
    tables : list of ndarray
        Conditional CDFs per axis (level ``k`` of shape ``map_shape[:k + 1]``).
    densities : ndarray, shape (prod(map_shape),)
        Density on the unit hypercube of each cell: of all axes
        (``mode='global'``) or of the non-image axes given the image cell
        (``mode='per-pixel'``).
    spp : int
        Samples per film pixel (``'global'``: on average).
    seed : int
        Any non-negative integer (:func:`~sparselt.rendering.mitsuba.launch.fold_seed`).
    mode : {'global', 'per-pixel'}
        ``'global'``: every sample picks a cell over all axes, the image
        plane included, and is splatted into the film pixel it lands in.
        ``'per-pixel'``: each pixel gets ``spp`` samples, jittered on the
        image plane, and the other axes follow the map's conditional at the
        pixel's image cell.

    Returns
    -------
    image : ndarray, shape (height, width, 3), float32
    nonfinite : int
        Samples that were NaN or infinite (counted as 0).
    """
    pixels = scene.width * scene.height

    def work(folded_seed):
        mi, dr = modules()
        # Global mode: the lanes run grouped by the film pixel they land in (the same samples, in another
        # order), so that neighbouring lanes trace neighbouring rays and read the same rows of the map.
        order = global_order(scene, layout, map_shape, tables, spp, folded_seed) if mode == "global" else None
        pixel, generator, _ = item_lanes(pixels, spp, folded_seed, stream=GUIDED_STREAM, order=order)
        width = dr.opaque(mi.UInt32, scene.width)
        first_axis = 0 if mode == "global" else 2
        uniforms = {name: generator.next_float32() for name in layout.dimensions}
        if mode == "per-pixel":
            uniforms["x"] = in_pixel(pixel % width, uniforms["x"], scene.width)
            uniforms["y"] = in_pixel(pixel // width, uniforms["y"], scene.height)
        if tables is None:  # no map: plain path tracing of the kind's estimator
            density = mi.Float(1.0)
        else:
            if mode == "per-pixel":
                cell_x = mi.UInt32(uniforms["x"] * dr.opaque(mi.Float, float(map_shape[0])))
                cell_y = mi.UInt32(uniforms["y"] * dr.opaque(mi.Float, float(map_shape[1])))
                prefix = dr.minimum(cell_x, map_shape[0] - 1) * map_shape[1] + dr.minimum(cell_y, map_shape[1] - 1)
            else:
                prefix = mi.UInt32(0)
            prefix = warp_axes(map_shape, tables, uniforms, layout.axes, prefix, first_axis)
            density = dr.gather(mi.Float, to_device(mi.Float, densities, np.float32), prefix)

        value, finite = zero_nonfinite(path_contribution(scene, layout, uniforms) / density, density > 0)
        scale = dr.opaque(mi.Float, 1.0 / int(spp))  # opaque: one kernel for every spp (a literal recompiles)
        if mode == "per-pixel":
            dr.eval(value, finite)
            sums = [dr.block_sum(channel, int(spp)) * scale for channel in (value.x, value.y, value.z)]
        else:  # splatted in lane order, on the host: the same bytes for the same seed, whatever the threads did
            target = film_pixel(scene, uniforms)
            weighted = [channel * scale for channel in (value.x, value.y, value.z)]
            dr.eval(weighted, target, finite)
            image = kernels.ordered_sums(np.asarray(target, dtype=np.uint32),
                                         [np.asarray(channel, dtype=np.float32) for channel in weighted], pixels)
            return image.reshape(scene.height, scene.width, 3), count_false(finite)
        dr.eval(sums, finite)
        return rgb_array(sums).reshape(scene.height, scene.width, 3), count_false(finite)

    return launch(work, seed, path_samples=pixels * int(spp))


def film_pixel(scene, uniforms):
    """Flat film pixel (row-major) of each lane's image-plane coordinates ``uniforms['x'], uniforms['y']``."""
    mi, dr = modules()
    target_x = dr.minimum(mi.UInt32(uniforms["x"] * scene.width), scene.width - 1)
    target_y = dr.minimum(mi.UInt32(uniforms["y"] * scene.height), scene.height - 1)
    return target_y * scene.width + target_x


def global_order(scene, layout, map_shape, tables, spp, seed):
    """The lanes of a global-mode render, grouped by the film pixel each lands in (stable within a pixel).

    A first, cheap kernel draws each lane's image-plane numbers and warps
    them through the map's first two levels exactly as the render does;
    a counting sort of the pixels gives the order. ``seed`` is the render's
    32-bit seed. Returns a ``mi.UInt32`` permutation of the lane numbers.
    """
    mi, dr = modules()
    pixels = scene.width * scene.height
    _, generator, _ = item_lanes(pixels, spp, seed, stream=GUIDED_STREAM)
    uniforms = {name: generator.next_float32() for name in layout.dimensions}  # unused draws are not computed
    if tables is not None:
        warp_axes(map_shape[:2], tables[:2], uniforms, layout.axes, mi.UInt32(0), 0)
    target = film_pixel(scene, uniforms)
    dr.eval(target)
    return to_device(mi.UInt32, kernels.counting_order(np.asarray(target, dtype=np.uint32), pixels), np.uint32)


def warp_axes(map_shape, tables, uniforms, names, prefix, first_axis):
    """Warp ``uniforms[names[k]]`` for ``k >= first_axis`` through the map's conditional CDFs, in place.

    One binary search per axis in the CDF row of the cells chosen so far; the
    remainder of the uniform inside the chosen interval is the jitter inside
    the cell. Returns the flat cell index (C order over ``map_shape``).
    """
    mi, dr = modules()
    for axis in range(first_axis, len(map_shape)):
        name = names[axis]
        length = int(map_shape[axis])
        table = to_device(mi.Float, tables[axis], np.float32)
        base = prefix * length
        value = uniforms[name]
        found = dr.binary_search(0, length - 1, lambda j: dr.gather(mi.Float, table, base + j) <= value)
        found = dr.minimum(found, length - 1)
        high = dr.gather(mi.Float, table, base + found)
        low = dr.select(found > 0, dr.gather(mi.Float, table, base + dr.maximum(found, 1) - 1), 0.0)
        width = high - low
        remainder = dr.clip(dr.select(width > 0, (value - low) / width, 0.5), 0.0, ONE_MINUS_EPSILON)
        uniforms[name] = dr.minimum((mi.Float(found) + remainder) * (1.0 / length), ONE_MINUS_EPSILON)
        prefix = base + found
    return prefix


def warp_points(map_shape, tables, uniforms, *, image_cells=None):
    """Run the guided renderer's in-kernel warp on explicit uniforms (for tests and diagnostics).

    Parameters
    ----------
    map_shape : tuple of int
    tables : list of ndarray
        :meth:`ImportanceMap.level_tables`.
    uniforms : ndarray, shape (n, D - first axis)
        Uniform numbers for the warped axes.
    image_cells : ndarray of int, optional
        Flat image-plane cells (the first two axes) to condition on; without
        them every axis is warped.

    Returns
    -------
    points : ndarray, shape like ``uniforms``
    cells : ndarray of int64, shape (n,)
        Flat cell of each point over the whole map.
    """
    initialize()
    mi, dr = modules()
    first_axis = 0 if image_cells is None else 2
    names = [f"axis{k}" for k in range(len(map_shape))]
    values = {names[first_axis + k]: to_device(mi.Float, uniforms[:, k], np.float32)
              for k in range(uniforms.shape[1])}
    if image_cells is None:
        prefix = dr.zeros(mi.UInt32, uniforms.shape[0])
    else:
        prefix = to_device(mi.UInt32, image_cells, np.uint32)
    cells = warp_axes(map_shape, tables, values, names, prefix, first_axis)
    dr.eval(cells, *values.values())
    points = np.stack([np.asarray(values[names[first_axis + k]], dtype=np.float64)
                       for k in range(uniforms.shape[1])], 1)
    return points, np.asarray(cells, dtype=np.int64)
