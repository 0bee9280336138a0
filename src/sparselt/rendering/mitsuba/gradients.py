"""Gradient-domain path samples: base paths and their offsets one pixel away, traced and reduced in one launch.

References
----------
M. Kettunen, M. Manzi, M. Aittala, J. Lehtinen, F. Durand and M. Zwicker,
"Gradient-domain path tracing", ACM TOG 34(4), 2015, sections 3 and 5.1
(the shift map; four neighbours).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .integrand import finite_lanes, path_contribution, zero_nonfinite
from .lanes import pss_vector, seeded_generator
from .launch import launch
from .readback import stacked
from .reconnection import shifted_pair, split_path
from .runtime import modules

GRADIENT_SHIFTS = {4: ((1, 0), (-1, 0), (0, 1), (0, -1)), 2: ((1, 0), (0, 1))}  # (dx, dy) per offset path
#: The shift maps: random replay of every number, or replay up to the first hit and reconnection to the base's
#: second vertex where it is diffuse (:mod:`sparselt.rendering.mitsuba.reconnection`).
SHIFT_MAPS = ("replay", "reconnection")
#: Lanes (base and offset paths) per replay launch. At most 10 values per lane come back (1.3 GB at the limit);
#: every launch adds its tracing and readback: at 1024x576, 16 spp in 8 launches of 2 took 0.6 s more than in 2.
GRADIENT_LANE_LIMIT = 1 << 25
#: Lanes (base samples, each with its 4 offsets) per reconnection launch. Its kernel is large: tracing it costs
#: about a second per launch (measured at 256x256: 16 spp in 16 launches took 3x as long as in one), so a launch
#: takes as many samples as memory allows (about 57 floats per lane come back: 1.9 GB at the limit).
RECONNECTION_LANE_LIMIT = 1 << 23


class GradientSamples(NamedTuple):
    """What :func:`sample_gradients` reduces per base pixel and shift in its one launch.

    Attributes
    ----------
    sums : ndarray, shape (height, width, 1 + offsets, 3), float64
        Per base pixel: the sum over its ``spp`` base samples of the base
        path's contribution (index 0) and of each offset path's (index
        ``1 + k`` for shift ``k``); 0 for offsets outside the film.
    camera_emission : ndarray, same shape
        The same sums of the part of each contribution that is emission
        seen directly by the camera ray (0 where the layout does not count it).
    albedo : ndarray, same shape
        The same sums of the diffuse reflectance at each path's first hit
        (0 for a miss or a surface without a diffuse lobe): the texture that
        :mod:`sparselt.methods.gradient_domain` demodulates. All 0 where
        :func:`sample_gradients` was told not to reduce it (``albedo=False``).
    nonfinite : int
        Paths (base or offset, inside the film) whose value was NaN or
        infinite, counted as 0.
    replayed : ndarray, shape (height, width, 1 + offsets, 3), or None
        The reconnection shift's sums, per base pixel and shift, of the parts
        of each path before its first bounce (emission seen directly, the
        first vertex's light sample): replayed, so each offset's is an
        unbiased sample of its pixel. ``None`` for the replay shift.
    pairs : ndarray, shape (height, width, offsets, 2, 3), or None
        The reconnection shift's sums per base pixel and shift of each side's
        multiple-importance-weighted tails (everything after the first hit):
        the base's (index 0) and the offset's (index 1)
        (:mod:`~sparselt.rendering.mitsuba.reconnection`). Under reconnection
        an offset's tail is not on its own an unbiased sample of its pixel
        (``sums`` still hold the offsets' whole values), the weighted pairs
        are. ``None`` for the replay shift, whose weights are all ½.
    """

    sums: np.ndarray
    camera_emission: np.ndarray
    albedo: np.ndarray
    nonfinite: int
    replayed: np.ndarray | None = None
    pairs: np.ndarray | None = None


def gradient_paths(width, height, offsets):
    """Paths traced per base sample per pixel of a ``width`` x ``height`` film: every base path, and every offset
    of :data:`GRADIENT_SHIFTS` ``[offsets]`` that lands inside the film (``5 w h - 2 (w + h)`` for 4 offsets)."""
    return width * height + sum((width - abs(dx)) * (height - abs(dy)) for dx, dy in GRADIENT_SHIFTS[offsets])


def launch_chunks(spp, per_launch, half=None):
    """The launches of ``spp`` base samples per pixel, at most ``per_launch`` each: ``(first, count, part)``.

    Without ``half``, ``part`` is 0. With ``half`` (the first half's samples
    are ``0 .. half - 1``), a launch holds samples of one part (``part`` 0 or
    1), or both halves evenly, split in the middle (``part`` None:
    ``first + count / 2 == half``), so that both halves of a small budget are
    one launch (one tracing of the kernel, one readback) while a launch
    that would straddle the half unevenly ends at it.
    """
    first = 0
    while first < spp:
        count = min(per_launch, spp - first)
        if half is not None and first < half < first + count and 2 * (half - first) != count:
            count = half - first
        if half is None or first + count <= half:
            part = 0
        elif first >= half:
            part = 1
        else:
            part = None
        yield first, count, part
        first += count


def sample_gradients(scene, layout, grid_shape, spp, seed, *, offsets=4, shift="replay", halves=False, albedo=True):
    """Gradient-domain path samples: every base sample replayed at the neighbouring pixels, in one kernel.

    Base sample ``i`` of pixel ``p`` is
    :func:`~sparselt.rendering.mitsuba.pixels.sample_pixels`' sample ``i``
    of ``p`` (the same random numbers). Its offset paths replay those
    numbers with the film position moved by exactly one pixel, to each
    neighbour of :data:`GRADIENT_SHIFTS` ``[offsets]`` (the shift map of
    primary sample space: a translation, Jacobian 1; Kettunen et al. 2015,
    3 and 5.1 use the 4 neighbours). An offset landing outside the film is
    not traced (counted 0). The base and offset paths of a pass are one
    Dr.Jit launch (lane ``((part * pixels + pixel) * (1 + offsets) + shift)
    * n + sample``), reduced per pixel and shift inside it: nothing per
    sample leaves it. Both halves of an even budget that fits one launch
    (:data:`GRADIENT_LANE_LIMIT`) are that launch (:func:`launch_chunks`:
    one tracing, one readback; in the methods' times the change was not
    measurable, docs/experiments/README.md, twelfth session).

    Parameters
    ----------
    scene : MitsubaScene
    layout : PathLayout
    grid_shape : tuple of int
        Signal grid (the cells are not used; the PSS vectors are those of
        :func:`~sparselt.rendering.mitsuba.pixels.sample_pixels`).
    spp : int
        Base samples per pixel.
    seed : int
        Any non-negative integer (:func:`~sparselt.rendering.mitsuba.launch.fold_seed`).
    offsets : {4, 2}
        Neighbours per base sample: ``+x, -x, +y, -y`` or ``+x, +y``.
    shift : {'replay', 'reconnection'}
        The shift map (:data:`SHIFT_MAPS`). ``'reconnection'`` needs the 4
        neighbours (its weights are two-sided) and returns ``pairs``.
    halves : bool
        Return the sums of base samples ``0 .. spp // 2 - 1`` and of the
        rest separately (two independent halves of the same samples, for the
        held-out choice of :mod:`sparselt.methods.gradient_domain`): the
        reconnection shift reduces both in its one launch. Needs ``spp >= 2``.
    albedo : bool
        Reduce the first hits' diffuse albedo (what demodulation needs). With
        False and the replay shift, ``albedo`` is left 0 and its three
        reductions are skipped (the reconnection shift reduces it always).

    Returns
    -------
    GradientSamples, or a tuple of two with ``halves``
        The sums of the paths' contributions, of their emission seen
        directly and of their first hits' diffuse albedo, per base pixel
        and shift, and the count of non-finite paths.
    """
    if offsets not in GRADIENT_SHIFTS:
        raise ValueError(f"offsets must be one of {sorted(GRADIENT_SHIFTS)}, got {offsets!r}")
    if shift not in SHIFT_MAPS:
        raise ValueError(f"shift must be one of {', '.join(SHIFT_MAPS)}, got {shift!r}")
    if shift == "reconnection" and offsets != 4:
        raise ValueError(f"the reconnection shift needs offsets=4 (its pairs are weighted from both sides), "
                         f"got offsets={offsets}")
    spp = int(spp)
    if spp < 1 or (halves and spp < 2):
        raise ValueError(f"spp must be >= {2 if halves else 1}{' to be halved' if halves else ''}, got {spp}")
    width, height = scene.width, scene.height
    if shift == "reconnection":
        def reconnection_work(folded_seed):
            parts = _reconnection_work(scene, layout, grid_shape, spp, folded_seed, spp // 2 if halves else None)
            return parts if halves else parts[0]

        return launch(reconnection_work, seed, path_samples=spp * gradient_paths(width, height, offsets))

    def work(folded_seed):
        """The replay shift's sums: every launch one chunk of :func:`launch_chunks`, each part reduced apart."""
        mi, dr = modules()
        shifts = ((0, 0),) + GRADIENT_SHIFTS[offsets]
        paths_per_base = len(shifts)
        pixels = width * height
        per_launch = max(1, min(spp, GRADIENT_LANE_LIMIT // (pixels * paths_per_base)))
        shift_x = mi.Int32([dx for dx, _ in shifts])
        shift_y = mi.Int32([dy for _, dy in shifts])
        outside_per_sample = paths_per_base * pixels - gradient_paths(width, height, offsets)
        half = spp // 2 if halves else None
        names = ("sums", "albedo", "camera_emission")
        reductions = [dict.fromkeys(names) for _ in range(2 if halves else 1)]
        nonfinite = [0] * len(reductions)
        for first, count, part in launch_chunks(spp, per_launch, half):
            # Lane ((part * pixels + pixel) * paths_per_base + shift) * block_size + sample: each part's blocks
            # (pixel by pixel, shift by shift) follow one another, so its block sums come back contiguous.
            parts = (part,) if part is not None else (0, 1)
            block_size = count // len(parts)
            index = dr.arange(mi.UInt32, pixels * paths_per_base * count)
            samples_per_block = dr.opaque(mi.UInt32, block_size)
            block = index // samples_per_block
            shift = block % dr.opaque(mi.UInt32, paths_per_base)
            pixel = (block // dr.opaque(mi.UInt32, paths_per_base)) % dr.opaque(mi.UInt32, pixels)
            part_block = block // dr.opaque(mi.UInt32, pixels * paths_per_base)
            sample_index = index % samples_per_block + part_block * samples_per_block + dr.opaque(mi.UInt32, first)
            generator = seeded_generator(pixel, sample_index, folded_seed, 0)
            film_width = dr.opaque(mi.Int32, width)
            target_x = mi.Int32(pixel % mi.UInt32(film_width)) + dr.gather(mi.Int32, shift_x, shift)
            target_y = mi.Int32(pixel // mi.UInt32(film_width)) + dr.gather(mi.Int32, shift_y, shift)
            inside = ((target_x >= 0) & (target_x < film_width) & (target_y >= 0)
                      & (target_y < dr.opaque(mi.Int32, height)))
            samples, _ = pss_vector(layout, grid_shape, generator, mi.UInt32(dr.select(inside, target_x, 0)),
                                    mi.UInt32(dr.select(inside, target_y, 0)), (width, height), cell=False)
            recorded = {}
            value, finite = zero_nonfinite(path_contribution(scene, layout, samples, recorded), inside)
            # A layout that counts no emission seen directly leaves its sums 0 without reducing zeros.
            channels = {"sums": [value.x, value.y, value.z]}
            if albedo:
                first_albedo = dr.select(finite, recorded["diffuse_albedo"], 0.0)
                channels["albedo"] = [first_albedo.x, first_albedo.y, first_albedo.z]
            if layout.count_camera_emission:
                emission = dr.select(finite, recorded["camera_emission"], 0.0)
                channels["camera_emission"] = [emission.x, emission.y, emission.z]
            # The kept lanes are counted by the same block sums (exact in float32: a block holds at most
            # GRADIENT_LANE_LIMIT / pixels lanes), not read back lane by lane.
            kept_lanes = dr.select(finite, mi.Float(1.0), mi.Float(0.0))
            flat = [channel for name in names for channel in channels.get(name, ())] + [kept_lanes]
            dr.eval(*flat)
            reduced = [dr.block_sum(channel, block_size) for channel in flat]
            dr.eval(reduced)
            reduced = [np.asarray(channel) for channel in reduced]
            blocks = pixels * paths_per_base
            for position, own in enumerate(parts):
                own_blocks = slice(position * blocks, (position + 1) * blocks)
                kept = int(np.sum(reduced[-1][own_blocks], dtype=np.float64))
                nonfinite[own] += blocks * block_size - kept - block_size * outside_per_sample
                column = 0
                for name in names:
                    if name in channels:
                        values = stacked([channel[own_blocks] for channel in reduced[column:column + 3]])
                        reduction = reductions[own]
                        reduction[name] = values if reduction[name] is None else reduction[name] + values
                        column += 3
        shape = (height, width, paths_per_base, 3)
        samples = tuple(GradientSamples(*(np.zeros(shape) if reduction[name] is None else reduction[name].reshape(shape)
                                          for name in ("sums", "camera_emission", "albedo")), bad_paths)
                        for reduction, bad_paths in zip(reductions, nonfinite))
        return samples if halves else samples[0]

    return launch(work, seed, path_samples=spp * gradient_paths(width, height, offsets))


def _reconnection_work(scene, layout, grid_shape, spp, folded_seed, half=None):
    """:func:`sample_gradients` with the reconnection shift: one lane per base sample, its 4 offsets in the lane.

    Returns a tuple of :class:`GradientSamples`: one, or with ``half`` two (base samples below ``half`` and the
    rest), reduced apart in the same launches.
    """
    mi, dr = modules()
    width, height = scene.width, scene.height
    shifts = GRADIENT_SHIFTS[4]
    pixels = width * height
    per_launch = max(1, min(spp, RECONNECTION_LANE_LIMIT // pixels))
    names = ("sums", "albedo", "camera_emission", "replayed")
    part_count = 1 if half is None else 2
    reductions = [{name: np.zeros((pixels, 1 + len(shifts), 3)) for name in names} for _ in range(part_count)]
    pairs = [np.zeros((pixels, len(shifts), 2, 3)) for _ in range(part_count)]
    nonfinite = [0] * part_count
    for first, count, part in launch_chunks(spp, per_launch, half):
        index = dr.arange(mi.UInt32, pixels * count)
        samples_per_pixel = dr.opaque(mi.UInt32, count)
        pixel = index // samples_per_pixel
        sample_index = index % samples_per_pixel + dr.opaque(mi.UInt32, first)
        film_width = dr.opaque(mi.Int32, width)
        pixel_x = mi.Int32(pixel % mi.UInt32(film_width))
        pixel_y = mi.Int32(pixel // mi.UInt32(film_width))
        base_samples, _ = pss_vector(layout, grid_shape, seeded_generator(pixel, sample_index, folded_seed, 0),
                                     mi.UInt32(pixel_x), mi.UInt32(pixel_y), (width, height), cell=False)
        base = split_path(scene, layout, base_samples)
        base_value, finite = zero_nonfinite(base.value)
        channels = {"sums": [base_value], "albedo": [base.albedo], "camera_emission": [base.camera_emission],
                    "replayed": [dr.select(finite, base.before_bounce, 0.0)]}
        pair_channels, bad = [], [~finite]
        for dx, dy in shifts:
            target_x, target_y = pixel_x + dx, pixel_y + dy
            inside = (target_x >= 0) & (target_x < film_width) & (target_y >= 0) & (target_y < dr.opaque(mi.Int32,
                                                                                                          height))
            offset_samples, _ = pss_vector(layout, grid_shape, seeded_generator(pixel, sample_index, folded_seed, 0),
                                           mi.UInt32(dr.select(inside, target_x, 0)),
                                           mi.UInt32(dr.select(inside, target_y, 0)), (width, height),
                                           cell=False)
            pair = shifted_pair(scene, layout, base, offset_samples, inside)
            offset_finite = (finite_lanes(pair.offset_value) & finite_lanes(pair.weighted_base)
                             & finite_lanes(pair.weighted_offset)
                             & finite & inside)
            bad.append(inside & ~offset_finite)
            keep = offset_finite
            channels["sums"].append(dr.select(keep, pair.offset_value, 0.0))
            channels["albedo"].append(dr.select(inside, pair.offset.albedo, 0.0))
            channels["camera_emission"].append(dr.select(inside, pair.offset.camera_emission, 0.0))
            channels["replayed"].append(dr.select(keep, pair.offset.before_bounce, 0.0))
            pair_channels += [dr.select(keep, pair.weighted_base, 0.0), dr.select(keep, pair.weighted_offset, 0.0)]
        flat = [value for name in names for value in channels[name]] + pair_channels
        scalars = [component for value in flat for component in (value.x, value.y, value.z)]
        dr.eval(scalars, bad)
        paths = 1 + len(shifts)

        def accumulate(part, reduced):
            values = stacked(reduced).reshape(pixels, -1, 3)
            for position, name in enumerate(names):
                reductions[part][name] += values[:, position * paths:(position + 1) * paths]
            pairs[part] += values[:, len(names) * paths:].reshape(pixels, len(shifts), 2, 3)

        if part is not None:  # the chunk is one part: one block per pixel
            reduced = [dr.block_sum(channel, count) for channel in scalars]
            dr.eval(reduced)
            nonfinite[part] += sum(int(np.count_nonzero(np.asarray(flag))) for flag in bad)
            accumulate(part, reduced)
        else:  # both halves, split in the middle: two blocks per pixel, no masks
            reduced = [dr.block_sum(channel, count // 2) for channel in scalars]
            dr.eval(reduced)
            lane_half = (sample_index >= dr.opaque(mi.UInt32, half))
            for part in (0, 1):
                in_part = lane_half if part else ~lane_half
                nonfinite[part] += sum(int(np.count_nonzero(np.asarray(flag & in_part))) for flag in bad)
                accumulate(part, [np.asarray(channel, dtype=np.float64)[part::2] for channel in reduced])
    shape = (height, width, 1 + len(shifts), 3)
    return tuple(GradientSamples(reduction["sums"].reshape(shape), reduction["camera_emission"].reshape(shape),
                                 reduction["albedo"].reshape(shape), bad_paths, reduction["replayed"].reshape(shape),
                                 pair.reshape(height, width, len(shifts), 2, 3))
                 for reduction, pair, bad_paths in zip(reductions, pairs, nonfinite))

