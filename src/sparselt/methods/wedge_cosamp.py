r"""Method ``wedge-cosamp``: CoSaMP per image tile, its support held to the tile's depth-of-field wedge.

Our own method, beyond the thesis: it asks whether knowing where the
spectrum lies rescues the thesis's 4-D CoSaMP (8.1). The samples are those
of ``cosamp`` (``spp`` per pixel at uniformly random lens cells, thesis
8.1.1) plus the camera-space depth of each sample's first hit. The grid
``(x, y, lens_u, lens_v)`` is cut into tiles of ``tile x tile`` pixels; each
tile is recovered on its own by CoSaMP on its gamma-mapped cell means
(eq. 7.1, as ``cosamp``), with the ``2K`` selection, and so the support,
restricted to the frequencies its depths allow: model-based compressive
sensing (Baraniuk et al. 2010) with the model "inside the wedge". The tiles'
reconstructions, put together, are the cross-fitted control variate of
``cosamp`` (:func:`~sparselt.methods.cosamp_reconstruction.cross_fitted_image`):
everything of the reconstruction trained on one fold, depths included, comes
from that fold alone, so the image keeps the mean of path tracing.

**The wedge** (Soler et al. 2009; Mehta et al. 2014, 3.1). A point at signed
circle of confusion ``c`` (pixels, :func:`~sparselt.filters.axis_aligned.circle_of_confusion`)
moves on the film by about ``c (2 u - 1)`` as the lens coordinate ``u``
crosses ``[0, 1)`` (Mitsuba's concentric map takes the square to the disc,
which scales the displacement along an axis by a factor ``s`` in
``[1/sqrt(2), 1]``); the same holds along ``y`` with ``v``. A tile of ``T``
grid pixels and ``U`` lens cells whose samples have circles of confusion in
``[c_lo, c_hi]`` (grid pixels) is then ``L(x, u) = f(x + alpha u)`` with
``alpha = 2 c s / U`` pixels per lens cell, and its 4-D DFT lies near

.. math:: k_u \equiv \frac{2 c s}{T} k_x \pmod U, \qquad
          k_v \equiv \frac{2 c s}{T} k_y \pmod V, \qquad
          c \in [c_\mathrm{lo}, c_\mathrm{hi}],\ s \in [2^{-1/2}, 1].

The mask is the product of the two 2-D wedges ``(k_x, k_u)`` and
``(k_y, k_v)``, each the set of integer bins within ``margin`` bins, along
both ``k_x`` and ``k_u``, of those lines, taken modulo the lens axis (the
aliasing of a shear faster than a lens cell allows wraps the line around),
and closed under ``k -> -k`` (conjugate pairs whole, as
:mod:`sparselt.fourier.hermitian` requires). The margin is one bin by
default: a tile is not periodic, so a line whose slope does not fall on
integer bins, cut to ``T`` pixels and ``U`` lens cells, spreads as a
Dirichlet kernel whose main lobe reaches one bin on either side (along
``k_x`` from the tile's cut, along ``k_u`` from the lens axis's); the
concentric map's factor ``s`` is in the lines' range already. A tile whose
range of lines covers a lens axis's whole period (large circles of
confusion at high ``k_x``) is unconstrained there.

**Measured** on dof-sculptures 250x250x16x16, every 25x25 tile rendered
densely (``sample_cells``, two independent renders of 8 spp per cell; the
clean spectrum as their cross-spectrum, so the noise's energy drops out; the
depth range of each tile from 20 spp of pixel samples, as a fold sees it),
over all 100 tiles, of the spectral energy other than each tile's zero
frequency:

============  ====================  ===============================
margin        energy in the wedge   spectrum the wedge covers (mean)
============  ====================  ===============================
0 bins        46.7%                 24.8%
1 (default)   90.2%                 47.5% (55.9% energy-weighted)
2 bins        97.5%                 74.0%
============  ====================  ===============================

(the noisy 8-spp spectrum: 80.9% in the default wedge; the median tile
88%). The sign of the shear was measured too: the wedge of ``+c`` along
both axes holds 90.2%, ``-c`` along both 79.2%, the mixed signs 81.6% and
86.5%. Of what the wedge misses we looked at two tiles: on the glossy
floor in front of the focal plane, energy at ``k_u = 0`` at every ``k_x``
(in focus: reflections, whose apparent depth is not the primary hit's); in
the background, an object seen from one edge of the lens only, which the
tile's samples did not hit. The wedge is not narrow here: the circles of
confusion of dof-sculptures reach 31 pixels at 250x250 (a shear of up to
2.5 tile widths across the lens), so the mean tile allows about half its
spectrum.

**Per tile**: ``K = N_tile / 200`` (the thesis's rate, per tile, with
``N_tile = T^2 U V``: 800 for 25x25x16x16 tiles); the option ``sparsity``
is K per tile, its default 0 standing for that rate, so that it follows
the ``tile`` option (a derived default sees only the grid); the tile's depth
range from its fold's samples (nearest and farthest first hit over every
pixel of the tile, ``inf`` for the environment), its circles of confusion
in grid pixels, the mask, :func:`~sparselt.methods.cosamp_reconstruction.reconstruct_luminance`
with ``allowed=mask``. A tile whose measurements are all equal (only the
constant environment, or black) is that constant without a solve: its zero
frequency fits it exactly, which is where CoSaMP would converge (after 7
iterations: a fifth of the tiles of dof-sculptures, a third of the time).
Tiles are solved in parallel threads, each with single-threaded FFTs (a
tile's transform is too small to share out).

**What it answers.** On dof-sculptures 250x250x16x16 at 40 spp (seed 1,
``sparselt compare``, 2 cores): relMSE 0.02133 against ``cosamp``'s
0.02135 and path tracing's 0.02100 at the same spp; ``beta`` 0.275
against 0.188 (the wedge's reconstruction explains more of the samples'
variation within a pixel); 6.3 s against ``cosamp``'s 5.8 s
(reconstruction 4.6 s each, medians of 3 runs). Knowing the support does
not rescue CoSaMP here (one seed): the wedge allows about half of each
tile's spectrum, and its reconstruction, though better than the full-grid
one, explains too little of the samples' variation to lower the error.

References
----------
Thesis 8.1 (the CoSaMP image methods). Baraniuk, R. G., Cevher, V., Duarte,
M. F., Hegde, C. (2010). Model-based compressive sensing. IEEE Trans. Inf.
Theory 56(4). Soler, C., Subr, K., Durand, F., Holzschuch, N., Sillion, F.
(2009). Fourier depth of field. ACM TOG 28(2). Mehta, S. U., Yao, J.,
Ramamoorthi, R., Durand, F. (2014). Factored axis-aligned filtering for
rendering multiple distribution effects. ACM TOG 33(4).
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from .. import kernels
from ..filters.axis_aligned import circle_of_confusion, depth_range
from ..fourier import fft
from .base import WARM_UP_SEED, Budget, Method, MethodResult, PhaseTimer
from .cosamp_reconstruction import CosampOptions, cross_fitted_image, default_sparsity, reconstruct_luminance
from .options import option
from .pixel_samples import cell_means, draw_pixel_samples
from .preconditions import GridMemory, MinimumSpp, ThinLens, TileDividesGrid, tiles_of
from .registry import register

#: Default tiles are the largest common divisor of the image axes up to this (25 for 250x250).
LARGEST_DEFAULT_TILE = 32
#: Bins added around the wedge along k_x and k_u (module docstring).
DEFAULT_MARGIN = 1.0
#: The concentric map scales a lens displacement along an axis by a factor in [1/sqrt(2), 1].
CONCENTRIC_SCALE = (1.0 / math.sqrt(2.0), 1.0)
#: The lens coordinate 2u - 1 spans 2 units of aperture radius over [0, 1).
LENS_SPAN = 2.0
DEPTH = "primary_depth"
#: ``sparsity`` 0: K = N_tile / 200 for the tile in use (a derived default cannot see the tile option).
AUTOMATIC_SPARSITY = 0


def default_tile(grid_shape):
    """The largest common divisor of the grid's image axes not above :data:`LARGEST_DEFAULT_TILE`."""
    common = math.gcd(int(grid_shape[0]), int(grid_shape[1]))
    return max(divisor for divisor in range(1, min(common, LARGEST_DEFAULT_TILE) + 1) if common % divisor == 0)


def _smaller_image_axis(grid_shape):
    return int(min(grid_shape[:2]))


@dataclass(frozen=True)
class WedgeCosampOptions(CosampOptions):
    """``cosamp``'s options (``sparsity`` per tile here) plus the tiling and the wedge's margin."""

    sparsity: int = option(AUTOMATIC_SPARSITY, minimum=0, section="8.1.1",
                           help="K per tile, the Fourier coefficients CoSaMP keeps in each tile; 0: the thesis's rate "
                                "1/200 of the tile's cells (N_tile/200, N_tile = tile^2 * lens_u * lens_v)")
    tile: int | None = option(None, derive=default_tile, default_text="largest common divisor of the image axes <= 32",
                              minimum=1, maximum=_smaller_image_axis, maximum_text="the smaller image axis",
                              help="tile side in grid pixels; must divide both image axes of the grid")
    margin: float = option(DEFAULT_MARGIN, minimum=0.0, maximum=8.0,
                           help="bins the wedge mask adds around the depth range's lines, along k_x and k_u")


def check_tiling(grid_shape, tile):
    """``(tiles along x, tiles along y)``; ValueError naming the fix when ``tile`` does not divide the image axes
    (:func:`~sparselt.methods.preconditions.tiles_of`, the check of its ``TileDividesGrid`` precondition)."""
    return tiles_of(grid_shape, tile, "wedge-cosamp.tile")


def check_lens(context):
    """The thin lens of the context's camera, refusing anything but a depth-of-field grid of a thin-lens camera.

    Raises
    ------
    ValueError
        The grid is not ``(x, y, lens_u, lens_v)``, or the camera is a pinhole.
    """
    axes = tuple(getattr(context.layout, "axes", ()))
    if context.kind != "dof" or axes != ("x", "y", "lens_u", "lens_v"):
        raise ValueError(f"wedge-cosamp needs kind 'dof' with axes x, y, lens_u, lens_v; got kind {context.kind!r} "
                         f"with axes {axes}")
    lens = context.scene.lens_geometry()
    if not lens["aperture_radius"] > 0:
        raise ValueError(f"wedge-cosamp derives its support from the lens's circles of confusion and needs a "
                         f"thin-lens camera; this one is a pinhole (aperture radius {lens['aperture_radius']!r}): "
                         "give --aperture")
    circle_of_confusion(np.inf, **lens)  # the analysis's own checks (focus distance)
    return lens


def _axis_wedge(spatial, lens, low, high, margin):
    """The 2-D wedge mask over ``(k_x, k_u)`` (DFT order) for circles of confusion in ``[low, high]`` grid pixels."""
    slowest = min(low * CONCENTRIC_SCALE[0], low * CONCENTRIC_SCALE[1])
    fastest = max(high * CONCENTRIC_SCALE[0], high * CONCENTRIC_SCALE[1])
    mask = np.zeros((spatial, lens), dtype=bool)
    frequencies = np.fft.fftfreq(spatial, 1.0 / spatial)
    for row, frequency in enumerate(frequencies):
        # k_u = (LENS_SPAN c s / T) k_x at the corners of k_x +- margin and c s in [slowest, fastest]: a bilinear
        # function, so its extremes over the box are at the corners.
        corners = [LENS_SPAN * shear / spatial * spatial_frequency
                   for spatial_frequency in (frequency - margin, frequency + margin) for shear in (slowest, fastest)]
        first = math.ceil(min(corners) - margin - 1e-9)
        last = math.floor(max(corners) + margin + 1e-9)
        if last - first + 1 >= lens:
            mask[row] = True
        else:
            mask[row, np.arange(first, last + 1) % lens] = True
    return mask | np.roll(np.flip(mask), 1, axis=(0, 1))  # k allowed exactly when -k is


def wedge_mask(tile_shape, circle_of_confusion_range, *, margin=DEFAULT_MARGIN):
    """The frequencies of a depth-of-field tile allowed by its depth range (module docstring).

    Parameters
    ----------
    tile_shape : tuple of int
        ``(T_x, T_y, U, V)``: the tile's grid, image axes first.
    circle_of_confusion_range : (float, float) or ((float, float), (float, float))
        Smallest and largest signed circle of confusion of the tile's points,
        in grid pixels; one pair for both image axes or one per axis.
    margin : float, optional
        Bins added around the lines, along the spatial and the lens axes.

    Returns
    -------
    ndarray of bool, shape ``tile_shape``
        Over the full 4-D spectrum in ``numpy.fft.fftn`` order;
        Hermitian-symmetric (``k`` allowed exactly when ``-k`` is), always
        holding the zero frequency.

    Raises
    ------
    ValueError
        A tile shape that is not 4-D, a range that is not finite or whose
        low end is above its high end, a negative margin.
    """
    tile_shape = tuple(int(size) for size in tile_shape)
    if len(tile_shape) != 4 or min(tile_shape) < 1:
        raise ValueError(f"tile_shape must be (T_x, T_y, U, V) of positive sizes, got {tile_shape}")
    ranges = np.broadcast_to(np.asarray(circle_of_confusion_range, dtype=np.float64), (2, 2))
    if not np.all(np.isfinite(ranges)) or np.any(ranges[:, 0] > ranges[:, 1]):
        raise ValueError(f"circle_of_confusion_range must be finite (low, high) pairs with low <= high, "
                         f"got {circle_of_confusion_range!r}")
    if not (math.isfinite(margin) and margin >= 0):
        raise ValueError(f"margin must be a finite number >= 0, got {margin!r}")
    along_x = _axis_wedge(tile_shape[0], tile_shape[2], ranges[0, 0], ranges[0, 1], margin)
    along_y = _axis_wedge(tile_shape[1], tile_shape[3], ranges[1, 0], ranges[1, 1], margin)
    return along_x[:, None, :, None] & along_y[None, :, None, :]


def tile_circles_of_confusion(samples, lens, grid_shape, tile):
    """Signed circle-of-confusion range of each tile's samples, in grid pixels along x and along y.

    Returns
    -------
    ndarray, shape (tiles along x, tiles along y, 2, 2)
        ``[tx, ty, axis, (low, high)]``.
    """
    width, height = samples.resolution
    upscale = (width // grid_shape[0], height // grid_shape[1])
    tiles_x, tiles_y = grid_shape[0] // tile, grid_shape[1] // tile
    nearest, farthest = depth_range(samples.per_pixel(samples.auxiliary[DEPTH]))
    nearest = nearest.reshape(tiles_y, tile * upscale[1], tiles_x, tile * upscale[0]).min(axis=(1, 3)).T
    farthest = farthest.reshape(tiles_y, tile * upscale[1], tiles_x, tile * upscale[0]).max(axis=(1, 3)).T
    # The circle of confusion increases with depth: the nearest and farthest hits bound it.
    low = circle_of_confusion(nearest, **lens)
    high = circle_of_confusion(farthest, **lens)
    film = np.stack([low, high], axis=-1)  # film pixels
    return np.stack([film / upscale[0], film / upscale[1]], axis=2)


def tile_cell_means(samples, grid_shape, tile):
    """Luminance measurements of the sampled cells, grouped by tile.

    :func:`~sparselt.methods.pixel_samples.cell_means` (a cell is measured
    by the mean luminance of its samples), its measured cells put in tile
    order by one sort.

    Returns
    -------
    local : ndarray of int64
        Each measured cell's flat index within its tile's grid
        ``(tile, tile, U, V)``, sorted within each tile.
    means : ndarray of float64
        The mean luminance of its samples.
    bounds : ndarray of int64, shape (tiles + 1,)
        Tile ``t`` (x-major: ``t = tx * tiles_y + ty``) holds entries
        ``bounds[t]:bounds[t + 1]``.
    """
    width, height = grid_shape[:2]
    lens_cells = math.prod(grid_shape[2:])
    tile_size = tile * tile * lens_cells
    cells, means, _ = cell_means(samples, math.prod(grid_shape), grid_shape)
    x, rest = np.divmod(cells, height * lens_cells)
    y, lens_cell = np.divmod(rest, lens_cells)
    tiles_y = height // tile
    key = ((x // tile) * tiles_y + y // tile) * tile_size + ((x % tile) * tile + y % tile) * lens_cells + lens_cell
    order = np.argsort(key)  # distinct keys: one per measured cell
    tile_of, local = np.divmod(key[order], tile_size)
    bounds = np.searchsorted(tile_of, np.arange((width // tile) * tiles_y + 1))
    return local, means[order], bounds


def _solve_tile(local, means, tile_shape, circle_of_confusion_range, *, gamma, sparsity, margin):
    """One tile: its wedge mask, and its restricted CoSaMP reconstruction or, for equal measurements, their value.

    Returns ``(reconstruction or constant, iterations, fraction of the spectrum the wedge allows)``.
    """
    mask = wedge_mask(tile_shape, circle_of_confusion_range, margin=margin)
    if means.min() == means.max():
        # The environment or black: the zero frequency alone fits exactly, where CoSaMP converges (7 iterations).
        return float(means[0]), 0, float(mask.mean())
    signal, result = reconstruct_luminance(local, means, tile_shape, gamma=gamma, sparsity=sparsity, allowed=mask,
                                           threads=1)
    return signal, result.iterations, float(mask.mean())


def wedge_reconstruction(train, grid_shape, lens, *, gamma, sparsity, tile, margin, timer=None, workers=None):
    """The grid's luminance from one fold's samples, tile by tile, each tile's support inside its wedge.

    Parameters
    ----------
    train : PixelSamples
        One fold, with the auxiliary quantity ``primary_depth``.
    grid_shape : tuple of int
        ``(width, height, U, V)``.
    lens : dict
        The thin lens (``lens_geometry()``).
    gamma : float
        Gamma of eq. 7.1.
    sparsity : int
        ``K`` per tile; 0 (:data:`AUTOMATIC_SPARSITY`): ``N_tile / 200``.
    tile : int
        Tile side in grid pixels (divides both image axes).
    margin : float
        The wedge's margin in bins.
    timer : PhaseTimer, optional
        Receives 'other' (bookkeeping) and 'reconstruction' (masks and solves).
    workers : int, optional
        Tiles solved at once, each with single-threaded FFTs (default: the
        FFT backend's thread count; a tile's FFT is too small to share).

    Returns
    -------
    reconstruction : ndarray, shape ``grid_shape``, float32
        Linear luminance. The same whatever ``workers``.
    record : dict
        Tiles, K, the mean fraction of the spectrum the wedges allow, CoSaMP
        iterations over the tiles, tiles solved (the others are constant).

    Raises
    ------
    ValueError
        K not below a tile's measured cells.
    """
    timer = timer or PhaseTimer()
    tile_shape = (tile, tile) + tuple(grid_shape[2:])
    count = default_sparsity(tile_shape) if sparsity == AUTOMATIC_SPARSITY else int(sparsity)
    tiles_x, tiles_y = check_tiling(grid_shape, tile)
    with timer("other"):
        local, means, bounds = tile_cell_means(train, grid_shape, tile)
        ranges = tile_circles_of_confusion(train, lens, grid_shape, tile)
        measured = np.diff(bounds)
        if measured.min() <= count:
            index = int(np.argmin(measured))
            raise ValueError(f"sparsity K={count} per tile must be below the measured cells of every tile (tile "
                             f"{divmod(index, tiles_y)} has {int(measured[index])}); raise --spp, lower "
                             "wedge-cosamp.sparsity or enlarge wedge-cosamp.tile")
    with timer("reconstruction"):
        reconstruction = np.zeros(grid_shape, dtype=np.float32)

        def solve(index):
            run = slice(bounds[index], bounds[index + 1])
            tx, ty = divmod(index, tiles_y)
            return _solve_tile(local[run], means[run], tile_shape, ranges[tx, ty], gamma=gamma, sparsity=count,
                               margin=margin)

        tiles = range(tiles_x * tiles_y)
        workers = min(len(tiles), workers or fft.default_threads())
        if workers > 1:
            with ThreadPoolExecutor(max_workers=workers) as pool:
                solved = list(pool.map(solve, tiles))
        else:
            solved = [solve(index) for index in tiles]
        for index, (signal, _, _) in enumerate(solved):
            tx, ty = divmod(index, tiles_y)
            reconstruction[tx * tile:(tx + 1) * tile, ty * tile:(ty + 1) * tile] = signal
    record = {"measured_cells": int(means.size), "tiles": len(tiles),
              "tiles_solved": sum(isinstance(signal, np.ndarray) for signal, _, _ in solved),
              "sparsity_per_tile": count,
              "wedge_fraction": float(np.mean([fraction for _, _, fraction in solved])),
              "cosamp_iterations": int(sum(iterations for _, iterations, _ in solved))}
    return reconstruction, record


def wedge_image_from_samples(samples, grid_shape, lens, *, gamma, sparsity, tile, margin, timer=None):
    """The ``wedge-cosamp`` image of a set of pixel samples with depths: everything after sampling.

    Returns
    -------
    image : ndarray, shape (height, width, 3), float32
    details : dict
        Tiles, K per tile, the mean wedge fraction of the spectrum, CoSaMP
        iterations, ``control_variate_coefficient`` (beta), per fold records.
    """
    timer = timer or PhaseTimer()
    width, height = samples.resolution
    upscale = (width // grid_shape[0], height // grid_shape[1])

    def reconstruct(train):
        return wedge_reconstruction(train, grid_shape, lens, gamma=gamma, sparsity=sparsity, tile=tile,
                                    margin=margin, timer=timer)

    image, beta, folds = cross_fitted_image(samples, reconstruct, upscale, timer=timer)
    details = {"gamma": gamma, "tile": tile, "margin": margin, "tiles": folds[0]["tiles"],
               "sparsity_per_tile": folds[0]["sparsity_per_tile"],
               "wedge_fraction": float(np.mean([fold["wedge_fraction"] for fold in folds])),
               "cosamp_iterations": sum(fold["cosamp_iterations"] for fold in folds),
               "control_variate_coefficient": beta, "folds": folds, "nonfinite_samples": samples.nonfinite}
    return image, details


@register
class WedgeCosamp(Method):
    """CoSaMP per tile with its support held to the tile's depth-of-field wedge, as cosamp's control variate."""

    name = "wedge-cosamp"
    description = ("4-D CoSaMP per image tile, support restricted to the wedge the tile's depths allow (model-based "
                   "CS), as a cross-fitted control variate (unbiased; ours, beyond the thesis)")
    kinds = ("dof",)
    family = "cosamp"
    needs_resolution_multiple = True
    Options = WedgeCosampOptions
    #: GridMemory: 61 bytes per cell beyond PT's peak measured on dof-sculptures' 64x64x32x32.
    requires = (ThinLens(), TileDividesGrid("tile"), MinimumSpp(2), GridMemory(80.0))

    def warm_up(self, context):
        check_lens(context)
        draw_pixel_samples(context, Budget(spp=1, seed=WARM_UP_SEED), auxiliary=(DEPTH,))
        kernels.warm_up()  # the numba loops around CoSaMP's FFTs

    def run(self, context, budget, timer):
        options = self.options
        with timer("other"):
            lens = check_lens(context)
            check_tiling(context.grid_shape, options.tile)
            if budget.spp < 2:
                raise ValueError(f"wedge-cosamp splits each pixel's samples in two folds and needs spp >= 2, "
                                 f"got {budget.spp}")
        with timer("sampling"):
            samples = draw_pixel_samples(context, budget, auxiliary=(DEPTH,))
        image, details = wedge_image_from_samples(samples, context.grid_shape, lens, gamma=options.gamma,
                                                  sparsity=options.sparsity, tile=options.tile,
                                                  margin=options.margin, timer=timer)
        return MethodResult(image=image, path_samples=samples.values.shape[0],
                            details=details)
