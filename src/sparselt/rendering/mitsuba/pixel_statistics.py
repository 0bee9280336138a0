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

from ... import kernels
from .integrand import path_contribution, zero_nonfinite
from .launch import launch
from .pixels import pixel_lanes
from .readback import stacked, to_device
from .runtime import modules

#: Per-pixel statistics :func:`sample_pixel_statistics` reduces, and their reduction.
#: ``rgb`` / ``rgb_squared``: the path contribution and its square; ``diffuse_rgb``: the contribution of samples
#: whose secondary ray came from a diffuse lobe, ``diffuse_rgb_squared`` its square; ``albedo``, ``normal``: the
#: camera hit's diffuse reflectance and
#: shading normal; ``depth``, ``hits``: the camera hit's depth and 1 (0 for a miss); ``nearest``, ``farthest``:
#: the camera hit's depth (``inf`` for a miss); ``shortest``: the diffuse-lobe secondary ray's length (``inf``
#: otherwise); ``direct_rgb``: the first vertex's direct lighting (``direct_light``, 0 where the contribution was
#: not finite); ``least_shadow_slope``, ``greatest_shadow_slope``: the slope ``s = d1 / d2 - 1`` of a blocked
#: light sample (``inf`` / ``-inf`` where not blocked; Mehta et al. 2012's ``s2`` and ``s1``);
#: ``least_penumbra``: ``sigma_l s`` of a blocked sample, the light's size times its slope (``inf`` otherwise),
#: what the soft shadow's bandlimit needs (:func:`sparselt.filters.axis_aligned.shadow_filter_width`);
#: ``path_vertices``: the vertices the sample's path reached (the camera hit and each bounce's hit; 0 for a
#: camera ray that misses), the allocation's cost model.
PIXEL_STATISTICS = {"rgb": "sum", "rgb_squared": "sum", "diffuse_rgb": "sum", "diffuse_rgb_squared": "sum",
                    "albedo": "sum", "normal": "sum",
                    "depth": "sum", "hits": "sum", "nearest": "min", "farthest": "max", "shortest": "min",
                    "direct_rgb": "sum", "least_shadow_slope": "min", "greatest_shadow_slope": "max",
                    "least_penumbra": "min", "path_vertices": "sum"}
#: Each reduction as the numpy ufunc that merges two partial results, and its identity.
REDUCTIONS = {"sum": (np.add, 0.0), "min": (np.minimum, np.inf), "max": (np.maximum, -np.inf)}


def statistic_quantity(name, value, recorded, finite=None):
    """The per-sample quantity behind a :data:`PIXEL_STATISTICS` name (``finite``: the lanes whose contribution
    was kept, :func:`~sparselt.rendering.mitsuba.integrand.zero_nonfinite`)."""
    mi, dr = modules()
    depth = recorded["primary_depth"]
    if name == "direct_rgb":
        return zero_nonfinite(recorded["direct_light"], finite)[0]
    if name in ("least_shadow_slope", "greatest_shadow_slope", "least_penumbra"):
        slope, blocked = shadow_slope(recorded)
        if name == "least_penumbra":
            return dr.select(blocked, recorded["light_size"] * slope, dr.inf)
        return dr.select(blocked, slope, dr.inf if name == "least_shadow_slope" else -dr.inf)
    if name == "rgb":
        return value
    if name == "path_vertices":
        return recorded["path_vertices"]
    if name == "rgb_squared":
        return value * value
    if name == "diffuse_rgb":
        return dr.select(recorded["secondary_diffuse"], value, 0.0)
    if name == "diffuse_rgb_squared":
        return dr.select(recorded["secondary_diffuse"], value * value, 0.0)
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


def shadow_slope(recorded):
    """``s = d1 / d2 - 1`` of each sample's blocked light sample (Mehta et al. 2012, 3), and the lanes blocked.

    ``d1`` (``light_distance``) is the distance from the receiver to the
    light point, ``d2`` (``occluder_distance``) from the light point to the
    blocker; the occlusion ``g(x + s y)`` of receiver point ``x`` and light
    point ``y`` has its spectrum on the line ``Omega_y = s Omega_x``.
    """
    _, dr = modules()
    distance, occluder = recorded["light_distance"], recorded["occluder_distance"]
    blocked = dr.isfinite(occluder) & dr.isfinite(distance) & (occluder > 0.0)
    return dr.select(blocked, distance / dr.select(blocked, occluder, 1.0) - 1.0, 0.0), blocked


def sample_pixel_statistics(scene, layout, grid_shape, seed, names, *, spp=None, lanes=None, halves=False,
                            first_sample=0):
    """Per-pixel reductions of per-sample quantities (:data:`PIXEL_STATISTICS`), reduced where they are drawn.

    The samples are exactly those of
    :func:`~sparselt.rendering.mitsuba.pixels.sample_pixels` (the same
    random numbers): ``spp`` per film pixel, or the explicit ``lanes``
    ``(pixels, sample_indices)`` sorted by pixel. Nothing per sample leaves
    the kernel: a uniform pass reduces each pixel's ``spp`` consecutive
    lanes with a block reduction; an explicit-lanes pass scatters each lane
    into its pixel's blocks of :data:`EXPLICIT_BLOCK` slots (padded with the
    reduction's identity), block-reduces them in the kernel and merges a
    pixel's few blocks on the host (:func:`explicit_slots`). Both are in a
    fixed order: the same seed gives the same bytes (atomic additions would
    not).

    Parameters
    ----------
    scene : MitsubaScene
    layout : PathLayout
    grid_shape : tuple of int
    seed : int
        Any non-negative integer (:func:`~sparselt.rendering.mitsuba.launch.fold_seed`).
    names : tuple of str
        Keys of :data:`PIXEL_STATISTICS`; only these are computed.
    spp : int, optional
        Samples per pixel of every film pixel (one of ``spp``, ``lanes``).
    lanes : tuple of two int arrays, optional
        ``(pixels, sample_indices)``, sorted by pixel.
    first_sample : int, optional
        A uniform pass's sample indices start here (default 0): ``spp``
        samples more of every pixel after the ``first_sample`` drawn
        before, the samples explicit lanes with those indices would draw.
    halves : bool, optional
        A uniform pass only (even ``spp``): reduce each pixel's first and
        second ``spp / 2`` samples apart, in the same launch (the block
        reduction's block is half as long), for a held-out check of what
        the first half predicts (``aaf-*``'s allocation).

    Returns
    -------
    statistics : dict, or a tuple of two dicts with ``halves``
        name -> float64 array ``(pixels,)`` or ``(pixels, 3)`` over every
        film pixel (pixels without samples hold the reduction's identity);
        with ``halves``, one such dict per half.
    nonfinite : int
        Samples that were NaN or infinite (counted as 0).

    Raises
    ------
    ValueError
        An unknown name, neither or both of ``spp`` and ``lanes``, lanes
        not sorted by pixel, ``halves`` with lanes or an odd ``spp``, or a
        ``first_sample`` with lanes.
    """
    unknown = sorted(set(names) - set(PIXEL_STATISTICS))
    if unknown:
        raise ValueError(f"unknown pixel statistics {unknown}; choose from {', '.join(PIXEL_STATISTICS)}")
    if (spp is None) == (lanes is None):
        raise ValueError("give exactly one of spp and lanes")
    if halves and (lanes is not None or int(spp) % 2):
        raise ValueError(f"halves needs a uniform pass of an even spp, not spp={spp} "
                         f"{'with explicit lanes' if lanes is not None else ''}".rstrip())
    if lanes is not None and first_sample:
        raise ValueError(f"first_sample applies to a uniform pass, got first_sample={first_sample} with explicit "
                         f"lanes (their sample indices are given)")
    pixels = scene.width * scene.height
    if lanes is not None:
        slots = explicit_slots(lanes[0], EXPLICIT_BLOCK)

    def work(folded_seed):
        mi, dr = modules()
        _, samples, _ = pixel_lanes(layout, grid_shape, spp, folded_seed, 0, pixels, (scene.width, scene.height),
                                    lanes, cell=False, first_sample=None if lanes is not None else first_sample)
        recorded = {}
        value, finite = zero_nonfinite(path_contribution(scene, layout, samples, recorded))
        quantities = {name: statistic_quantity(name, value, recorded, finite) for name in names}
        flat = {name: [quantity.x, quantity.y, quantity.z] if dr.size_v(quantity) == 3 else [quantity]
                for name, quantity in quantities.items()}
        operations = {"sum": dr.ReduceOp.Add, "min": dr.ReduceOp.Min, "max": dr.ReduceOp.Max}
        if lanes is None:
            block = int(spp) // 2 if halves else int(spp)
        else:  # each lane into its slot: a pixel's lanes fill whole blocks, the rest of a block is the identity
            block = slots.block
            slot = to_device(mi.UInt32, slots.slot, np.uint32)
            padded = {}
            for name, channels in flat.items():
                identity = REDUCTIONS[PIXEL_STATISTICS[name]][1]
                padded[name] = [dr.full(mi.Float, identity, slots.block_count * block) for _ in channels]
                # Evaluated buffers, not literals: a literal of the launch's own size would fold into the kernel,
                # whose code (and cache entry) would then depend on whether the padding happens to add nothing.
                dr.make_opaque(*padded[name])
                for target, channel in zip(padded[name], channels):
                    dr.scatter(target, channel, slot)
            flat = padded
        dr.eval(finite, *[channel for channels in flat.values() for channel in channels])  # the one path kernel
        nonfinite = dr.count(~finite)
        reduced = {name: [dr.block_reduce(operations[PIXEL_STATISTICS[name]], channel, block, mode="evaluated")
                          for channel in channels] for name, channels in flat.items()}
        dr.eval(nonfinite, *[channel for channels in reduced.values() for channel in channels])
        results = {name: stacked(channels) for name, channels in reduced.items()}
        if lanes is not None:
            results = {name: slots.merge(value, PIXEL_STATISTICS[name], pixels) for name, value in results.items()}
        if halves:  # blocks alternate between a pixel's first and second half
            results = tuple({name: value[part::2] for name, value in results.items()} for part in (0, 1))
        return results, int(nonfinite[0])

    drawn = pixels * int(spp) if lanes is None else int(np.size(lanes[0]))
    return launch(work, seed, path_samples=drawn)


#: Slots per block of an explicit-lanes pass (:func:`sample_pixel_statistics`): a pixel's lanes fill
#: ``ceil(count / EXPLICIT_BLOCK)`` blocks, reduced in the kernel; the host merges each pixel's blocks.
EXPLICIT_BLOCK = 16


class ExplicitSlots:
    """Where each lane of an explicit-lanes pass goes: whole blocks per pixel (see :func:`explicit_slots`).

    Attributes
    ----------
    slot : ndarray of uint32
        Each lane's slot in the padded array (``block_count * block`` slots).
    block : int
        Slots per block.
    block_count : int
    owners : ndarray of int64
        The pixel of each run of lanes (in lane order).
    first_blocks : ndarray of int64
        Each run's first block.
    """

    def __init__(self, slot, block, block_count, owners, first_blocks):
        self.slot, self.block, self.block_count = slot, block, block_count
        self.owners, self.first_blocks = owners, first_blocks

    def merge(self, partial, reduction, pixels):
        """Per-pixel reductions from the per-block ones ``partial`` (``(block_count, ...)``), over ``pixels``."""
        operation, identity = REDUCTIONS[reduction]
        result = np.full((pixels,) + partial.shape[1:], identity)
        if self.owners.size:
            result[self.owners] = operation.reduceat(partial, self.first_blocks, axis=0)
        return result


def explicit_slots(pixel_ids, block):
    """The padded block layout of explicit lanes ``pixel_ids`` (sorted by pixel): an :class:`ExplicitSlots`.

    Lane ``i`` of a run of ``n`` lanes of one pixel starting at lane ``s``
    goes to slot ``b * block + (i - s)``, ``b`` the run's first block; the
    run owns ``ceil(n / block)`` blocks. A block reduction then sums (or
    takes the minimum of) each block's lanes in a fixed order, and a pixel's
    blocks are merged on the host in block order.

    Raises
    ------
    ValueError
        ``pixel_ids`` not sorted (a pixel's lanes must be consecutive).
    """
    pixel_ids = np.ascontiguousarray(pixel_ids, dtype=np.int64)
    if pixel_ids.size and np.any(pixel_ids[1:] < pixel_ids[:-1]):
        raise ValueError("explicit lanes must be sorted by pixel")
    starts = np.flatnonzero(np.concatenate(([True], pixel_ids[1:] != pixel_ids[:-1]))) if pixel_ids.size else \
        np.zeros(0, dtype=np.int64)
    counts = np.diff(np.append(starts, pixel_ids.size))
    blocks = -(-counts // block)
    first_blocks = np.cumsum(blocks) - blocks
    slot = kernels.run_ramps(counts, first_blocks * block, 1, np.uint32)
    return ExplicitSlots(slot, int(block), int(blocks.sum()), pixel_ids[starts], first_blocks)
