r"""Gaussian, bilateral and cross-bilateral filters on n-D arrays (thesis 8.2, 8.4; eq. 8.1-8.3).

For an array ``I`` over a grid of any dimension, a window of
``(2 r + 1)^D`` offsets clipped at the border (no padding values enter the
sum) and guides ``G_1 .. G_m`` with range sigmas ``sigma_g``:

.. math:: \tilde I(p) = \frac{1}{W_p} \sum_{q \in \Omega_p} I(q)\,
          \exp\Big(-\frac{\lVert p - q\rVert^2}{2\sigma_s^2}\Big)
          \prod_{g=1}^{m} \exp\Big(-\frac{\lVert G_g(p) - G_g(q)\rVert^2}{2\sigma_g^2}\Big)

with ``W_p`` the sum of the weights: eq. 8.3. The bilateral filter (eq.
8.1-8.2) is the case of one guide, the image itself; the Gaussian filter has
no guide. ``\lVert G_g(p) - G_g(q)\rVert`` is the Euclidean norm over the
guide's channels, ``\lVert p - q\rVert`` over the grid offsets.

The kernels are compiled with numba and run in parallel: for 2-D grids
(images) one row at a time, one window offset at a time across the row, with
a call-free exponential that vectorises; for other dimensions one point at a
time over the clipped window. Spatial weights are tabulated once per call and
the range weights of all guides share one exponential per neighbour.

References
----------
Tomasi, C. and Manduchi, R. (1998). Bilateral filtering for gray and color
images. ICCV. Eisemann, E. and Durand, F. (2004), Petschnigg et al. (2004):
joint (cross) bilateral filtering. Thesis 8.2.1, eq. 8.1-8.3; 8.4.
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from ..checks import check_positive_finite

_KERNEL = None


def _compiled_kernel():
    """The numba kernel, compiled on first use (and cached on disk by numba)."""
    global _KERNEL
    if _KERNEL is None:
        import numba

        @numba.njit(parallel=True, fastmath=False, cache=True)
        def kernel(values, guides, coefficients, shape, strides, offsets, spatial, out):
            points = values.shape[0]
            channels = values.shape[1]
            guide_channels = guides.shape[1]
            dimensions = shape.shape[0]
            block = 1024
            for first in numba.prange((points + block - 1) // block):
                coordinate = np.empty(dimensions, dtype=np.int64)
                accumulated = np.empty(channels, dtype=np.float64)
                for point in range(first * block, min(points, (first + 1) * block)):
                    for axis in range(dimensions):
                        coordinate[axis] = (point // strides[axis]) % shape[axis]
                    accumulated[:] = 0.0
                    total = 0.0
                    for index in range(offsets.shape[0]):
                        neighbour = 0
                        inside = True
                        for axis in range(dimensions):
                            position = coordinate[axis] + offsets[index, axis]
                            if position < 0 or position >= shape[axis]:
                                inside = False
                                break
                            neighbour += position * strides[axis]
                        if not inside:
                            continue
                        exponent = 0.0
                        for channel in range(guide_channels):
                            difference = guides[point, channel] - guides[neighbour, channel]
                            exponent += coefficients[channel] * difference * difference
                        weight = spatial[index] * math.exp(-exponent)
                        total += weight
                        for channel in range(channels):
                            accumulated[channel] += weight * values[neighbour, channel]
                    for channel in range(channels):
                        out[point, channel] = accumulated[channel] / total
            return out

        _KERNEL = kernel
    return _KERNEL


_KERNEL_2D = None


def _compiled_kernel_2d():
    """Image kernel: rows in parallel, one window offset at a time over a whole row (vectorisable).

    The exponential is ``exp(-e) = exp(-e / 64) ** 64`` with a degree-14 Taylor
    polynomial on ``[-0.625, 0]`` and six squarings (relative error below
    1e-13), so the inner loop has no call and vectorises; exponents are capped
    at 40 (weights below ``4e-18`` of the centre's, under float64 rounding).
    """
    global _KERNEL_2D
    if _KERNEL_2D is None:
        import numba

        @numba.njit(parallel=True, cache=True)
        def kernel(values, guides, coefficients, radius_y, radius_x, spatial, out):
            channels, height, width = values.shape
            guide_channels = guides.shape[0]
            for y in numba.prange(height):
                total = np.zeros(width)
                accumulated = np.zeros((channels, width))
                weight = np.empty(width)
                for dy in range(-radius_y, radius_y + 1):
                    row = y + dy
                    if row < 0 or row >= height:
                        continue
                    for dx in range(-radius_x, radius_x + 1):
                        spatial_weight = spatial[dy + radius_y, dx + radius_x]
                        start = max(0, -dx)
                        stop = min(width, width - dx)
                        count = stop - start
                        # Slices starting at index 0: the loops below index from 0 up, which lets the
                        # compiler drop numba's negative-index handling and vectorise.
                        here = weight[start:stop]
                        here[:] = 0.0
                        for channel in range(guide_channels):
                            coefficient = coefficients[channel]
                            centre = guides[channel, y, start:stop]
                            neighbour = guides[channel, row, start + dx:stop + dx]
                            for x in range(count):
                                difference = centre[x] - neighbour[x]
                                here[x] += coefficient * difference * difference
                        sums = total[start:stop]
                        for x in range(count):
                            u = -min(here[x], 40.0) * 0.015625
                            p = 1.0 / 87178291200.0
                            p = p * u + 1.0 / 6227020800.0
                            p = p * u + 1.0 / 479001600.0
                            p = p * u + 1.0 / 39916800.0
                            p = p * u + 1.0 / 3628800.0
                            p = p * u + 1.0 / 362880.0
                            p = p * u + 1.0 / 40320.0
                            p = p * u + 1.0 / 5040.0
                            p = p * u + 1.0 / 720.0
                            p = p * u + 1.0 / 120.0
                            p = p * u + 1.0 / 24.0
                            p = p * u + 1.0 / 6.0
                            p = p * u + 0.5
                            p = p * u + 1.0
                            p = p * u + 1.0
                            p = p * p
                            p = p * p
                            p = p * p
                            p = p * p
                            p = p * p
                            p = p * p
                            p *= spatial_weight
                            here[x] = p
                            sums[x] += p
                        for channel in range(channels):
                            target = accumulated[channel, start:stop]
                            source = values[channel, row, start + dx:stop + dx]
                            for x in range(count):
                                target[x] += here[x] * source[x]
                for channel in range(channels):
                    for x in range(width):
                        out[channel, y, x] = accumulated[channel, x] / total[x]
            return out

        _KERNEL_2D = kernel
    return _KERNEL_2D


def _as_points(array, name, spatial_shape, *, channel_axis):
    """(points, channels) float64 view of an array over ``spatial_shape`` (channels last)."""
    array = np.asarray(array)
    if not np.issubdtype(array.dtype, np.number) or np.iscomplexobj(array):
        raise TypeError(f"{name} must be a real numeric array, got dtype {array.dtype}")
    if channel_axis is not None:
        array = np.moveaxis(array, channel_axis, -1)
    if spatial_shape is None:
        spatial_shape = array.shape if channel_axis is None else array.shape[:-1]
    if array.shape == tuple(spatial_shape):
        points = array.reshape(-1, 1)
    elif array.shape[:-1] == tuple(spatial_shape):
        points = array.reshape(-1, array.shape[-1])
    else:
        raise ValueError(f"{name} has shape {array.shape}; it must cover the image's grid {tuple(spatial_shape)} "
                         "(optionally with a trailing channel axis)")
    if points.size == 0:
        raise ValueError(f"{name} is empty")
    if not np.all(np.isfinite(points)):
        raise ValueError(f"{name} has {int(np.count_nonzero(~np.isfinite(points)))} NaN or infinite values")
    return np.ascontiguousarray(points, dtype=np.float64), tuple(spatial_shape)


def _check_radius(radius, dimensions):
    """One non-negative integer radius per grid axis (a single integer applies to every axis)."""
    radii = [radius] * dimensions if isinstance(radius, (numbers.Integral, bool, float)) else list(radius)
    if len(radii) != dimensions:
        raise ValueError(f"radius has {len(radii)} entries for a {dimensions}-D grid; give one or one per axis")
    for value in radii:
        if isinstance(value, bool) or not isinstance(value, numbers.Integral):
            raise TypeError(f"radius must be an integer (or one per axis), got {radius!r}")
        if value < 0:
            raise ValueError(f"radius must be >= 0, got {radius}")
    return [int(value) for value in radii]


def _window(radii, sigma_spatial):
    grids = np.meshgrid(*[np.arange(-r, r + 1) for r in radii], indexing="ij")
    offsets = np.stack([grid.reshape(-1) for grid in grids], axis=1).astype(np.int64)
    squared = np.sum(offsets.astype(np.float64) ** 2, axis=1)
    return offsets, np.exp(-squared / (2.0 * sigma_spatial**2))


def cross_bilateral(image, guides, radius, sigma_spatial, sigma_range, *, channel_axis=None):
    """Cross (joint) bilateral filter of ``image`` with range guides (eq. 8.3), on any number of dimensions.

    Parameters
    ----------
    image : ndarray
        The array to filter, over a grid of any dimension; with
        ``channel_axis`` one axis holds channels (filtered with the same weights).
    guides : sequence of ndarray
        Range guides over the same grid, each optionally with a trailing
        channel axis (the range distance is the Euclidean norm over it). An
        empty sequence gives the Gaussian filter.
    radius : int or sequence of int
        Window half-width: ``(2 radius + 1)`` points along every grid axis
        (or one radius per axis, e.g. ``(2, 2, 1, 1)`` for a 5x5x3x3 window),
        clipped at the border.
    sigma_spatial : float
        Spatial sigma, in grid points.
    sigma_range : float or sequence of float
        One range sigma for every guide, or one per guide.
    channel_axis : int, optional
        Axis of ``image`` that holds channels (``-1`` for an RGB image); the
        guides' channels, if any, are their last axis.

    Returns
    -------
    ndarray
        The filtered image, same shape as ``image``, float64 (float32 for
        float32 input).

    Raises
    ------
    TypeError
        Non-integer radius, non-numeric arrays, a guide list that is not a sequence.
    ValueError
        Radius < 0, sigmas not positive and finite, guides whose grid differs
        from the image's, NaN or infinite values, a wrong number of range sigmas.
    """
    sigma_spatial = check_positive_finite(sigma_spatial, "sigma_spatial")
    if isinstance(guides, np.ndarray) or not isinstance(guides, (list, tuple)):
        raise TypeError("guides must be a list or tuple of arrays (use [guide] for one guide)")
    values, grid = _as_points(image, "image", None, channel_axis=channel_axis)
    radii = _check_radius(radius, len(grid))
    if np.isscalar(sigma_range) or isinstance(sigma_range, numbers.Real):
        sigmas = [sigma_range] * len(guides)
    else:
        sigmas = list(sigma_range)
        if len(sigmas) != len(guides):
            raise ValueError(f"sigma_range has {len(sigmas)} values for {len(guides)} guides; give one or one per guide")
    guide_columns, coefficients = [], []
    for number, (guide, sigma) in enumerate(zip(guides, sigmas)):
        sigma = check_positive_finite(sigma, f"sigma_range[{number}]")
        points, _ = _as_points(guide, f"guide {number}", grid, channel_axis=None)
        guide_columns.append(points)
        coefficients += [1.0 / (2.0 * sigma**2)] * points.shape[1]
    guide_points = (np.concatenate(guide_columns, axis=1) if guide_columns
                    else np.zeros((values.shape[0], 0), dtype=np.float64))
    offsets, spatial = _window(radii, sigma_spatial)
    strides = np.cumprod((1,) + grid[:0:-1])[::-1].astype(np.int64)
    coefficients = np.asarray(coefficients, dtype=np.float64)
    if len(grid) == 2:
        planes = np.ascontiguousarray(values.T.reshape(values.shape[1], *grid))
        guide_planes = np.ascontiguousarray(guide_points.T.reshape(guide_points.shape[1], *grid))
        result = np.empty_like(planes)
        _compiled_kernel_2d()(planes, guide_planes, coefficients, radii[0], radii[1],
                              spatial.reshape(2 * radii[0] + 1, 2 * radii[1] + 1), result)
        out = result.reshape(values.shape[1], -1).T
    else:
        out = np.empty_like(values)
        _compiled_kernel()(values, np.ascontiguousarray(guide_points), coefficients,
                           np.asarray(grid, dtype=np.int64), strides, offsets, spatial, out)
    image = np.asarray(image)
    result_dtype = np.float32 if image.dtype == np.float32 else np.float64
    if channel_axis is None:
        return out.reshape(grid).astype(result_dtype, copy=False)
    moved = out.reshape(grid + (values.shape[1],)).astype(result_dtype, copy=False)
    return np.moveaxis(moved, -1, channel_axis)


def bilateral(image, radius, sigma_spatial, sigma_range, *, channel_axis=None):
    """Bilateral filter (eq. 8.1-8.2): the cross-bilateral filter guided by the image itself."""
    guide = np.moveaxis(np.asarray(image), channel_axis, -1) if channel_axis is not None else image
    return cross_bilateral(image, [guide], radius, sigma_spatial, sigma_range, channel_axis=channel_axis)


def gaussian(image, sigma, *, radius=None, channel_axis=None):
    """Gaussian filter with the same window and border rule as the bilateral filters.

    ``radius`` defaults to ``ceil(3 sigma)``; weights are renormalised where
    the window is clipped at the border.
    """
    sigma = check_positive_finite(sigma, "sigma")
    radius = int(math.ceil(3.0 * sigma)) if radius is None else radius
    return cross_bilateral(image, [], radius, sigma, 1.0, channel_axis=channel_axis)
