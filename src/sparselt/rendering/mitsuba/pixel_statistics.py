"""Per-pixel statistics of the pixel samples, reduced in the kernel that draws them.

The axis-aligned filters (Mehta et al. 2012-2014, ``aaf-dof`` and
``aaf-indirect``) need per-pixel sums, minima and maxima of per-sample
quantities; these reduce them where they are drawn, so nothing per sample
leaves the kernel.

References
----------
S. U. Mehta, B. Wang and R. Ramamoorthi, "Axis-aligned filtering for
interactive sampled soft shadows" (2012); S. U. Mehta et al., "Axis-aligned
filtering for interactive physically-based diffuse indirect lighting" (2013);
S. U. Mehta et al., "Factored axis-aligned filtering for rendering multiple
distribution effects" (2014).
"""

from __future__ import annotations

import numpy as np

from .integrand import path_contribution, zero_nonfinite
from .launch import launch
from .pixels import pixel_lanes
from .readback import count_false, stacked
from .runtime import modules

#: Per-pixel statistics :func:`sample_pixel_statistics` reduces, and their reduction.
#: ``rgb`` / ``rgb_squared``: the path contribution and its square; ``diffuse_rgb``: the contribution of samples
#: whose secondary ray came from a diffuse lobe; ``albedo``, ``normal``: the camera hit's diffuse reflectance and
#: shading normal; ``depth``, ``hits``: the camera hit's depth and 1 (0 for a miss); ``nearest``, ``farthest``:
#: the camera hit's depth (``inf`` for a miss); ``shortest``: the diffuse-lobe secondary ray's length (``inf``
#: otherwise).
PIXEL_STATISTICS = {"rgb": "sum", "rgb_squared": "sum", "diffuse_rgb": "sum", "albedo": "sum", "normal": "sum",
                    "depth": "sum", "hits": "sum", "nearest": "min", "farthest": "max", "shortest": "min"}
#: Each reduction as the numpy ufunc that merges two partial results, and its identity.
REDUCTIONS = {"sum": (np.add, 0.0), "min": (np.minimum, np.inf), "max": (np.maximum, -np.inf)}


def statistic_quantity(name, value, recorded):
    """The per-sample quantity behind a :data:`PIXEL_STATISTICS` name."""
    mi, dr = modules()
    depth = recorded["primary_depth"]
    if name == "rgb":
        return value
    if name == "rgb_squared":
        return value * value
    if name == "diffuse_rgb":
        return dr.select(recorded["secondary_diffuse"], value, 0.0)
    if name == "albedo":
        return recorded["diffuse_albedo"]
    if name == "normal":
        return recorded["primary_normal"]
    if name == "depth":
        return dr.select(dr.isfinite(depth), depth, 0.0)
    if name == "hits":
        return dr.select(dr.isfinite(depth), mi.Float(1.0), mi.Float(0.0))
    if name in ("nearest", "farthest"):
        return mi.Float(depth)
    return dr.select(recorded["secondary_diffuse"], recorded["secondary_distance"], dr.inf)  # shortest


def sample_pixel_statistics(scene, layout, grid_shape, seed, names, *, spp=None, lanes=None):
    """Per-pixel reductions of per-sample quantities (:data:`PIXEL_STATISTICS`), reduced where they are drawn.

    The samples are exactly those of
    :func:`~sparselt.rendering.mitsuba.pixels.sample_pixels` (the same
    random numbers): ``spp`` per film pixel, or the explicit ``lanes``
    ``(pixels, sample_indices)`` sorted by pixel. Nothing per sample leaves
    the kernel but the sums of an explicit-lanes pass, which are reduced in
    numpy (in a fixed order: the same seed gives the same bytes; the
    kernel's atomic additions would not).

    Parameters
    ----------
    scene : MitsubaScene
    layout : PathLayout
    grid_shape : tuple of int
    seed : int
        Any non-negative integer (:func:`~sparselt.rendering.mitsuba.launch.fold_seed`).
    names : tuple of str
        Keys of :data:`PIXEL_STATISTICS`.
    spp : int, optional
        Samples per pixel of every film pixel (one of ``spp``, ``lanes``).
    lanes : tuple of two int arrays, optional

    Returns
    -------
    statistics : dict
        name -> float64 array ``(pixels,)`` or ``(pixels, 3)`` over every
        film pixel (pixels without samples hold the reduction's identity).
    nonfinite : int
        Samples that were NaN or infinite (counted as 0).
    """
    unknown = sorted(set(names) - set(PIXEL_STATISTICS))
    if unknown:
        raise ValueError(f"unknown pixel statistics {unknown}; choose from {', '.join(PIXEL_STATISTICS)}")
    if (spp is None) == (lanes is None):
        raise ValueError("give exactly one of spp and lanes")
    pixels = scene.width * scene.height

    def work(folded_seed):
        _, dr = modules()
        _, samples, _ = pixel_lanes(layout, grid_shape, spp, folded_seed, 0, pixels, (scene.width, scene.height),
                                    lanes)
        recorded = {}
        value, finite = zero_nonfinite(path_contribution(scene, layout, samples, recorded))
        quantities = {name: statistic_quantity(name, value, recorded) for name in names}
        flat = {name: [quantity.x, quantity.y, quantity.z] if dr.size_v(quantity) == 3 else [quantity]
                for name, quantity in quantities.items()}
        dr.eval(finite, *[channel for channels in flat.values() for channel in channels])
        nonfinite = count_false(finite)
        results = {}
        if lanes is None:
            operations = {"sum": dr.ReduceOp.Add, "min": dr.ReduceOp.Min, "max": dr.ReduceOp.Max}
            reduced = {name: [dr.block_reduce(operations[PIXEL_STATISTICS[name]], channel, int(spp))
                              for channel in channels] for name, channels in flat.items()}
            dr.eval(*[channel for channels in reduced.values() for channel in channels])
            for name, channels in reduced.items():
                results[name] = stacked(channels)
            return results, nonfinite
        pixel_ids = np.ascontiguousarray(lanes[0], dtype=np.int64)
        starts = np.flatnonzero(np.concatenate(([True], pixel_ids[1:] != pixel_ids[:-1])))
        owners = pixel_ids[starts]
        for name, channels in flat.items():
            reduction = PIXEL_STATISTICS[name]
            per_lane = stacked(channels)
            operation, identity = REDUCTIONS[reduction]
            result = np.full((pixels,) + per_lane.shape[1:], identity)
            if owners.size:
                result[owners] = operation.reduceat(per_lane, starts, axis=0)
            results[name] = result
        return results, nonfinite

    drawn = pixels * int(spp) if lanes is None else int(np.size(lanes[0]))
    return launch(work, seed, path_samples=drawn)
