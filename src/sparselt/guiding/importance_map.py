r"""Piecewise-constant importance maps over primary sample space (thesis 6.2.1 eq. 6.3-6.5; 8.3; 9.3).

A map over a grid of ``N`` cells with non-negative values ``R`` defines the
density on the unit hypercube

.. math:: p(u) = N \Big((1 - d)\,\frac{R(c(u))}{\sum_i R(i)} + \frac{d}{N}\Big),

eq. 6.3 mixed with the uniform density by the defensive weight ``d``
(Hesterberg 1995; the thesis's future work 9.3), ``c(u)`` the cell holding
``u``. The mixture guarantees ``p(u) >= d``: a wrong map can at most multiply
the variance of a path tracer's estimate by ``1 / d``. Sampling the mixture is
sampling this one piecewise-constant density, so the one-sample balance
heuristic between map and uniform (selection probabilities ``1 - d``, ``d``)
is the same estimator and needs no separate code.

Sampling inverts the CDF (eq. 6.4-6.5) one axis at a time: the marginal CDF of
axis 0, then the CDF of axis 1 given the cell of axis 0, and so on. The
remainder of each uniform inside the chosen interval is the jitter inside the
cell, so ``D`` uniforms give a point; the cell is distributed exactly as eq.
6.5 over the flat CDF picks it, and the point is uniform inside it.
"""

from __future__ import annotations

import math
import numbers

import numpy as np


def _check_defensive(defensive):
    if isinstance(defensive, bool) or not isinstance(defensive, numbers.Real):
        raise TypeError(f"defensive must be a number in [0, 1], got {defensive!r}")
    if not 0.0 <= float(defensive) <= 1.0:
        raise ValueError(f"defensive must be in [0, 1], got {defensive!r}")
    return float(defensive)


class ImportanceMap:
    """A piecewise-constant density over ``[0, 1)^D`` from cell values.

    Parameters
    ----------
    values : array_like
        Non-negative finite cell values, one axis per PSS dimension of the map
        (for example the luminance of a reconstruction).
    defensive : float, optional
        Weight of the uniform density in the mixture, in ``[0, 1]`` (default 0.1).
    clamp_negative : bool, optional
        Set negative values to zero instead of refusing them (a Fourier
        reconstruction undershoots near edges).

    Raises
    ------
    ValueError
        NaN or infinite values, negative values (without ``clamp_negative``),
        defensive outside ``[0, 1]``, or a map with no mass and ``defensive = 0``
        (it has no density).

    Attributes
    ----------
    pdf : ndarray
        Cell probabilities, the grid's shape, summing to 1.
    """

    def __init__(self, values, *, defensive=0.1, clamp_negative=False):
        values = np.asarray(values, dtype=np.float64)
        if values.ndim == 0 or values.size == 0:
            raise ValueError(f"an importance map needs at least one axis and one cell, got shape {values.shape}")
        if not np.all(np.isfinite(values)):
            raise ValueError(f"importance map has {int(np.count_nonzero(~np.isfinite(values)))} NaN or infinite values")
        if values.min() < 0:
            if not clamp_negative:
                raise ValueError(f"importance map has {int(np.count_nonzero(values < 0))} negative values "
                                 f"(smallest {float(values.min()):.3g}); pass clamp_negative=True to set them to 0")
            values = np.maximum(values, 0.0)
        self.defensive = _check_defensive(defensive)
        total = float(values.sum())
        if total <= 0 and self.defensive == 0:
            raise ValueError("importance map is all zero and defensive = 0: it has no density; "
                             "give a map with some positive value or defensive > 0")
        self.shape = values.shape
        self.size = values.size
        uniform = 1.0 / self.size
        mapped = values / total if total > 0 else np.full(values.shape, uniform)
        self.pdf = (1.0 - self.defensive) * mapped + self.defensive * uniform
        self._tables = None

    # -- hierarchical CDFs ---------------------------------------------------

    def level_tables(self):
        """Conditional CDFs, one per axis: ``tables[k]`` has shape ``shape[:k + 1]``.

        ``tables[k][i_0, .., i_{k-1}, :]`` is the CDF (ending at 1) of axis
        ``k`` given the cells of the axes before it; a prefix of zero mass gets
        a uniform CDF.
        """
        if self._tables is None:
            tables = []
            mass = self.pdf
            marginals = [mass]
            for axis in range(len(self.shape) - 1, 0, -1):
                mass = mass.sum(axis=axis)
                marginals.append(mass)
            marginals = marginals[::-1]  # marginals[k] has shape shape[:k + 1]
            for marginal in marginals:
                cumulative = np.cumsum(marginal, axis=-1)
                totals = cumulative[..., -1:]
                length = marginal.shape[-1]
                uniform = np.arange(1, length + 1) / length
                with np.errstate(invalid="ignore", divide="ignore"):
                    table = np.where(totals > 0, cumulative / np.where(totals > 0, totals, 1.0), uniform)
                table[..., -1] = 1.0
                tables.append(table)
            self._tables = tables
        return self._tables

    def _check_unit(self, u, name, dimensions):
        u = np.asarray(u, dtype=np.float64)
        if u.ndim != 2 or u.shape[1] != dimensions:
            raise ValueError(f"{name} must have shape (n, {dimensions}), got {u.shape}")
        if not np.all((u >= 0) & (u < 1)):
            raise ValueError(f"{name} must lie in [0, 1)^{dimensions}")
        return u

    def sample(self, u):
        """Warp uniform points to the map's density.

        Parameters
        ----------
        u : array_like, shape (n, D)
            Uniform points in ``[0, 1)^D``.

        Returns
        -------
        points : ndarray, shape (n, D)
            Points in ``[0, 1)^D`` distributed with :meth:`density`.
        density : ndarray, shape (n,)
            The density of each point on the unit hypercube.
        """
        u = self._check_unit(u, "u", len(self.shape))
        return self._warp(u, prefix=np.zeros(u.shape[0], dtype=np.int64), first_axis=0)

    def _warp(self, u, prefix, first_axis):
        tables = self.level_tables()
        points = np.empty_like(u)
        for column, axis in enumerate(range(first_axis, len(self.shape))):
            length = self.shape[axis]
            rows = tables[axis].reshape(-1, length)[prefix]
            index = np.minimum((rows <= u[:, column:column + 1]).sum(axis=1), length - 1)
            low = np.where(index > 0, rows[np.arange(len(index)), np.maximum(index - 1, 0)], 0.0)
            high = rows[np.arange(len(index)), index]
            width = high - low
            with np.errstate(invalid="ignore", divide="ignore"):
                remainder = np.where(width > 0, (u[:, column] - low) / np.where(width > 0, width, 1.0), 0.5)
            remainder = np.clip(remainder, 0.0, np.nextafter(1.0, 0.0))
            points[:, column] = (index + remainder) / length
            prefix = prefix * length + index
        return points, self._density_of_cells(prefix, first_axis)

    def cell_densities(self, image_axes=0):
        """Density of each cell (flat, C order) on the unit hypercube.

        ``image_axes = 0``: the density over all axes, ``pdf * N``. Otherwise
        the density over the remaining axes given the cell of the first
        ``image_axes`` axes: ``pdf / (mass of its image cell) * cells per image cell``.
        """
        if image_axes == 0:
            return self.pdf.reshape(-1) * self.size
        image_cells = math.prod(self.shape[:image_axes])
        rest = self.size // image_cells
        flat = self.pdf.reshape(image_cells, rest)
        return (flat / flat.sum(axis=1, keepdims=True)).reshape(-1) * rest

    def _density_of_cells(self, cells, first_axis):
        return self.cell_densities(first_axis)[cells]

    def density(self, points):
        """Density on the unit hypercube of ``points`` (shape (n, D), in ``[0, 1)^D``)."""
        points = self._check_unit(points, "points", len(self.shape))
        return self.pdf.reshape(-1)[self.cells_of(points)] * self.size

    def cells_of(self, points):
        """Flat C-order cell of each point."""
        points = np.asarray(points, dtype=np.float64)
        coordinates = [np.minimum((points[:, axis] * n).astype(np.int64), n - 1) for axis, n in enumerate(self.shape)]
        return np.ravel_multi_index(coordinates, self.shape)

    def conditional(self, image_axes=2):
        """The map conditioned on the first ``image_axes`` axes (the image plane): see :class:`ConditionalMap`."""
        return ConditionalMap(self, image_axes)


class ConditionalMap:
    """Sampling the non-image axes of an :class:`ImportanceMap` given an image-plane cell (per-pixel guiding).

    ``sample(image_cells, u)`` draws, for each flat image cell, a point of the
    remaining axes from ``pdf(rest | image cell)`` (the defensive mixture is
    inherited, so the conditional density is at least ``defensive`` wherever
    the image cell's mass is at most its uniform share).
    """

    def __init__(self, importance_map, image_axes):
        if not 0 < image_axes < len(importance_map.shape):
            raise ValueError(f"image_axes must be between 1 and {len(importance_map.shape) - 1}, got {image_axes}")
        self.map = importance_map
        self.image_axes = int(image_axes)
        self.image_shape = importance_map.shape[:image_axes]
        self.rest_shape = importance_map.shape[image_axes:]

    def sample(self, image_cells, u):
        """Points of the non-image axes (n, D - image_axes) and their conditional density."""
        image_cells = np.asarray(image_cells, dtype=np.int64)
        u = self.map._check_unit(u, "u", len(self.rest_shape))
        if image_cells.shape != (u.shape[0],):
            raise ValueError(f"image_cells must have one entry per row of u ({u.shape[0]}), got {image_cells.shape}")
        if image_cells.size and (image_cells.min() < 0 or image_cells.max() >= math.prod(self.image_shape)):
            raise ValueError(f"image cells must be in [0, {math.prod(self.image_shape)})")
        return self.map._warp(u, prefix=image_cells, first_axis=self.image_axes)

    def density(self, image_cells, points):
        """Conditional density of non-image ``points`` given their image cells."""
        image_cells = np.asarray(image_cells, dtype=np.int64)
        points = self.map._check_unit(points, "points", len(self.rest_shape))
        rest = [np.minimum((points[:, k] * n).astype(np.int64), n - 1) for k, n in enumerate(self.rest_shape)]
        cells = image_cells * math.prod(self.rest_shape) + np.ravel_multi_index(rest, self.rest_shape)
        return self.map._density_of_cells(cells, self.image_axes)
