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


def sample_pixel_statistics(scene, layout, grid_shape, seed, names, *, spp=None, counts=None, halves=False,
                            first_sample=0):
    """Per-pixel reductions of per-sample quantities (:data:`PIXEL_STATISTICS`), reduced where they are drawn.

    The samples are exactly those of
    :func:`~sparselt.rendering.mitsuba.pixels.sample_pixels` (the same
    random numbers): ``spp`` per film pixel, or ``counts[p]`` of pixel
    ``p`` (an allocation). Nothing per sample leaves the kernel: a uniform
    pass reduces each pixel's ``spp`` consecutive lanes with a block
    reduction; an allocation is drawn in one launch (several past
    :data:`LANE_LIMIT` lanes) as blocks of :data:`ALLOCATION_BLOCK`
    consecutive samples of one pixel, block-reduced in the kernel, and each
    pixel's remaining samples as single lanes (:func:`allocation_layouts`);
    the host merges each pixel's blocks, then its single lanes
    (:func:`sparselt.kernels.merge_runs`). Both are in a fixed order: the
    same seed gives the same bytes (atomic additions would not).

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
        Samples per pixel of every film pixel (one of ``spp``, ``counts``).
    counts : array of int, optional
        Samples of each film pixel (row-major, ``width * height`` values,
        non-negative; 0: none).
    first_sample : int, optional
        Sample indices start here (default 0): ``spp`` (or ``counts[p]``)
        samples more of every pixel after the ``first_sample`` drawn before.
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
        An unknown name, neither or both of ``spp`` and ``counts``, counts
        of another size than the film's pixels or negative, ``halves`` with
        counts or an odd ``spp``.
    """
    unknown = sorted(set(names) - set(PIXEL_STATISTICS))
    if unknown:
        raise ValueError(f"unknown pixel statistics {unknown}; choose from {', '.join(PIXEL_STATISTICS)}")
    if (spp is None) == (counts is None):
        raise ValueError("give exactly one of spp and counts")
    if halves and (counts is not None or int(spp) % 2):
        raise ValueError(f"halves needs a uniform pass of an even spp, not spp={spp} "
                         f"{'with counts' if counts is not None else ''}".rstrip())
    pixels = scene.width * scene.height
    if counts is not None:
        counts = np.asarray(counts)
        if counts.size != pixels or not np.issubdtype(counts.dtype, np.integer) or np.any(counts < 0):
            raise ValueError(f"counts must be {pixels} non-negative integers (one per film pixel), got "
                             f"{counts.size} of {counts.dtype}" + (" with negatives" if np.any(counts < 0) else ""))
        layouts = allocation_layouts(counts.reshape(-1), int(first_sample), lane_limit=LANE_LIMIT)

    def drawn_pass(folded_seed, block, lane_arguments):
        """One launch (its lanes :func:`~sparselt.rendering.mitsuba.pixels.pixel_lanes`'s ``lane_arguments``):
        the per-sample channels, each ``block`` consecutive ones reduced, and the kept lanes' count."""
        mi, dr = modules()
        _, samples, _ = pixel_lanes(layout, grid_shape, seed=folded_seed, film_size=(scene.width, scene.height),
                                    cell=False, **lane_arguments)
        recorded = {}
        value, finite = zero_nonfinite(path_contribution(scene, layout, samples, recorded))
        quantities = {name: statistic_quantity(name, value, recorded, finite) for name in names}
        flat = {name: [quantity.x, quantity.y, quantity.z] if dr.size_v(quantity) == 3 else [quantity]
                for name, quantity in quantities.items()}
        dr.eval(finite, *[channel for channels in flat.values() for channel in channels])  # the one path kernel
        nonfinite = dr.count(~finite)
        operations = {"sum": dr.ReduceOp.Add, "min": dr.ReduceOp.Min, "max": dr.ReduceOp.Max}
        reduced = {name: [dr.block_reduce(operations[PIXEL_STATISTICS[name]], channel, block, mode="evaluated")
                          if block else channel for channel in channels] for name, channels in flat.items()}
        dr.eval(nonfinite, *[channel for channels in reduced.values() for channel in channels])
        return flat, reduced, int(nonfinite[0])

    def work(folded_seed):
        mi, _ = modules()
        if counts is None:
            block = int(spp) // 2 if halves else int(spp)
            _, reduced, nonfinite = drawn_pass(folded_seed, block, {"spp": int(spp), "first_pixel": 0,
                                                                    "pixel_count": pixels, "first_sample": first_sample})
            results = {name: stacked(channels) for name, channels in reduced.items()}
            if halves:  # blocks alternate between a pixel's first and second half
                results = tuple({name: value[part::2] for name, value in results.items()} for part in (0, 1))
            return results, nonfinite
        results = {name: np.full((pixels, 3) if name in VECTOR_STATISTICS else pixels,
                                 REDUCTIONS[PIXEL_STATISTICS[name]][1]) for name in names}
        nonfinite = 0
        for part in layouts:  # whole pixels each: the same bytes however the launches split
            tables = [np.concatenate(pair) for pair in ((part.block_pixels, part.single_pixels),
                                                        (part.block_first_samples, part.single_samples))]
            # Dr.Jit compiles a launch of one lane, or a gather from one element, as other kernels (not warmed):
            # the last unit is listed twice (and a lone single lane drawn twice, the copy dropped).
            tables = [to_device(mi.UInt32, np.append(table, table[-1:]), np.uint32) for table in tables]
            blocked = part.block * part.block_pixels.size
            lane_count = blocked + part.single_pixels.size
            flat, reduced, bad = drawn_pass(folded_seed, part.block if blocked else 0, {
                "spp": part.block, "first_pixel": 0, "pixel_count": 0,
                "units": (max(lane_count, 2), part.block, part.block_pixels.size, *tables)})
            nonfinite += bad if lane_count > 1 else bad // 2
            for name in names:  # a pixel's blocks, then its single lanes
                kernels.merge_runs(results[name], [np.asarray(channel)[:part.block_pixels.size]
                                                   for channel in reduced[name]], *part.block_runs,
                                   PIXEL_STATISTICS[name])
                kernels.merge_runs(results[name], [np.asarray(channel)[blocked:lane_count] for channel in flat[name]],
                                   *part.single_runs, PIXEL_STATISTICS[name])
        return results, nonfinite

    drawn = pixels * int(spp) if counts is None else int(counts.sum())
    return launch(work, seed, path_samples=drawn)


#: An allocation's pass (:func:`allocation_layouts`) draws a pixel's samples in blocks of this many, reduced in the
#: kernel, and the rest one lane each, merged on the host.
ALLOCATION_BLOCK = 16
#: The most lanes one launch of an allocation's pass holds (every per-sample channel is evaluated once). Larger
#: launches were slower, not faster: at 1024x576 and 64 spp, 2^24 instead of 2^22 made the sampling phase 6.0 -> 7.2 s
#: on checker-dof and 16.4 -> 18.5 s on courtyard (issue 37, tenth session, one run of 2 seeds each, when lanes were
#: scattered into padded slots).
LANE_LIMIT = 1 << 22
#: Statistics with three channels.
VECTOR_STATISTICS = frozenset({"rgb", "rgb_squared", "diffuse_rgb", "diffuse_rgb_squared", "albedo", "normal",
                               "direct_rgb"})


class AllocationLayout:
    """The lanes of one launch of an allocation's pass (see :func:`allocation_layouts`).

    Attributes
    ----------
    block : int
        Samples per block.
    block_pixels, block_first_samples : ndarray of int64
        Each block's film pixel and first sample index, in pixel order.
    single_pixels, single_samples : ndarray of int64
        Each single lane's film pixel and sample index, in pixel order.
    block_runs, single_runs : tuple of two int64 arrays
        ``(pixels, starts)``: the pixels that have blocks (single lanes)
        and where each one's run of them starts, then their total
        (:func:`~sparselt.kernels.merge_runs`).
    """

    def __init__(self, block, pixels, full, rest, first_sample):
        self.block = int(block)
        self.block_pixels = kernels.run_ramps(full, pixels, 0, np.int64)
        self.block_first_samples = kernels.run_ramps(full, np.full(pixels.size, int(first_sample)), block, np.int64)
        self.single_pixels = kernels.run_ramps(rest, pixels, 0, np.int64)
        self.single_samples = kernels.run_ramps(rest, first_sample + full * block, 1, np.int64)
        self.block_runs, self.single_runs = (
            (pixels[runs > 0], np.concatenate(([0], np.cumsum(runs[runs > 0])))) for runs in (full, rest))


def allocation_layouts(counts, first_sample=0, block=ALLOCATION_BLOCK, lane_limit=LANE_LIMIT):
    """An allocation's samples as launches of whole pixels: a list of :class:`AllocationLayout`.

    Pixel ``p``'s samples ``first_sample .. first_sample + counts[p] - 1``
    are ``counts[p] // block`` blocks of ``block`` consecutive samples
    (reduced in the kernel by one block reduction over the launch) and
    ``counts[p] % block`` single lanes after every block of the launch
    (read back and merged on the host): one launch for any allocation, no
    lane spent on padding, nothing scattered. Pixels go to launches whole,
    in pixel order, a new launch where the running count of lanes passes a
    multiple of ``lane_limit`` (so at most ``lane_limit`` plus one pixel's
    lanes each); pixels without samples are in none.
    """
    counts = np.asarray(counts, dtype=np.int64).reshape(-1)
    drawn = np.flatnonzero(counts)
    launch_of = (np.cumsum(counts[drawn]) - 1) // max(1, int(lane_limit))
    layouts = []
    for group in np.split(drawn, np.flatnonzero(np.diff(launch_of)) + 1) if drawn.size else []:
        layouts.append(AllocationLayout(block, group, counts[group] // block, counts[group] % block, first_sample))
    return layouts
