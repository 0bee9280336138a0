"""Primary-sample-space layouts: which random number drives which decision.

This module is pure Python: it decides *what* each dimension of the primary
sample space (PSS) means for each signal kind. The renderer adapter
(:mod:`sparselt.rendering.mitsuba`) consumes a :class:`PathLayout` and
evaluates ``f(S(u))`` for explicit vectors ``u``.

Dimension order of a PSS vector (thesis 2.1.6, 3.2.2; Kelemen et al. 2002):

1. ``x``, ``y``: position on the image plane, in ``[0, 1)`` over the whole
   film. With the box pixel filter used throughout, cell ``i`` of an image
   axis of resolution ``n`` is exactly pixel ``i``.
2. ``lens_u``, ``lens_v``: aperture sample, present only for a thin-lens camera.
3. For each path vertex ``k = 1, 2, ...`` (the k-th surface hit):

   - ``light{k}_u``, ``light{k}_v``: next-event estimation (the emitter
     sample; Mitsuba uses it to choose the emitter as well), only where the
     vertex does next-event estimation;
   - ``bsdf{k}_u``, ``bsdf{k}_v``: the 2-D BSDF direction sample;
   - ``lobe{k}``: the 1-D sample that Mitsuba's ``BSDF.sample`` uses to choose
     among several lobes (dielectric reflection or refraction, plastic
     coating or base, ...). It has its own dimension so that the 2-D direction
     sample keeps its meaning. It is never a signal axis: the thesis counts 4
     dimensions per bounce, so the lobe choice is integrated by jittering,
     like every dimension that is not an axis.

Every dimension that is not an axis of the signal is drawn uniformly at random
for each of the jittered samples of a cell, so a cell value is the mean of
``f(S(u))`` over the cell's box in the axis dimensions and over the whole unit
interval in the others.

Kinds and the estimators they use (``D`` is the maximum path depth in
Mitsuba's convention: ``D = 1`` shows emitters only, ``D = 2`` adds direct
light, ``D = 3`` one indirect bounce):

``path`` (thesis 5.3)
    Mitsuba's ``path`` integrator without Russian roulette: emission seen by
    the camera ray, then at each vertex ``1 .. D-1`` next-event estimation and
    BSDF sampling combined with the power heuristic. Axes ``x, y`` plus the
    four light and BSDF dimensions of each vertex: ``2 + 4 (D - 1)`` axes.
``path-indirect`` (thesis 5.3)
    The same dimensionality without direct light: no light sample and no
    emission at the first vertex, next-event estimation with MIS at vertices
    ``2 .. D-1``, and an extra BSDF sample at vertex ``D`` whose emission
    hit is counted with weight 1. Its integrated image is the radiance of
    paths of length ``3 .. D + 1`` (Mitsuba ``path`` at depth ``D + 1`` minus
    depth 2).
``dof`` (thesis 7.1)
    The ``path`` estimator on a thin-lens camera with axes
    ``x, y, lens_u, lens_v``; everything else random.
``indirect`` (thesis 7.2)
    Axes ``x, y, bsdf1_u, bsdf1_v``: the secondary ray chosen at the first
    vertex. No emission and no light sample at the first vertex (that would be
    its direct light); from the second vertex on, next-event estimation and
    BSDF sampling with MIS as in ``path``. At ``D = 3`` the value is the
    one-bounce indirect light carried by the secondary ray; the integrated
    image equals Mitsuba ``path`` at depth ``D`` minus depth 2.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..checks import check_integer

KINDS = ("path", "path-indirect", "dof", "indirect")
IMAGE_AXES = ("x", "y")
LENS_AXES = ("lens_u", "lens_v")


@dataclass(frozen=True)
class VertexPlan:
    """What the path does at one surface vertex.

    Attributes
    ----------
    next_event : bool
        Sample a point on an emitter (two dimensions) and add its contribution.
    count_emission_hit : bool
        Add the emission found where the BSDF-sampled ray from this vertex
        lands. Weighted by the power heuristic when ``next_event`` is true,
        with weight one otherwise.
    """

    next_event: bool
    count_emission_hit: bool


@dataclass(frozen=True)
class PathLayout:
    """The meaning of every PSS dimension for one signal kind and depth.

    Attributes
    ----------
    kind : str
        One of :data:`KINDS`.
    max_depth : int
        Longest path, in Mitsuba's convention.
    thin_lens : bool
        Whether the camera has an aperture (adds ``lens_u``, ``lens_v``).
    count_camera_emission : bool
        Add the emission seen directly by the camera ray.
    vertices : tuple of VertexPlan
        One plan per surface vertex, in path order.
    dimensions : tuple of str
        Every PSS dimension in the order the renderer consumes them.
    axes : tuple of str
        The dimensions that are gridded into the signal, in signal-axis order.
    """

    kind: str
    max_depth: int
    thin_lens: bool
    count_camera_emission: bool
    vertices: tuple
    dimensions: tuple
    axes: tuple

    def axis_positions(self):
        """Index into :attr:`dimensions` of each signal axis."""
        return tuple(self.dimensions.index(axis) for axis in self.axes)


def vertex_dimensions(index, plan):
    """Names of the PSS dimensions one vertex consumes, in order."""
    names = []
    if plan.next_event:
        names += [f"light{index}_u", f"light{index}_v"]
    names += [f"bsdf{index}_u", f"bsdf{index}_v", f"lobe{index}"]
    return names


def _minimum_depth(kind):
    return {"path": 1, "dof": 1, "path-indirect": 2, "indirect": 3}[kind]


def path_layout(kind, max_depth=3, *, thin_lens=False, hide_emitters=False):
    """Build the :class:`PathLayout` of a signal kind.

    Parameters
    ----------
    kind : {'path', 'path-indirect', 'dof', 'indirect'}
        Signal kind (thesis sections 5.3, 7.1, 7.2).
    max_depth : int, optional
        Longest path in Mitsuba's convention (default 3, as the thesis).
    thin_lens : bool, optional
        Whether the camera is a thin lens. ``dof`` requires it.
    hide_emitters : bool, optional
        Do not count emitters seen directly by the camera (Mitsuba's
        ``hide_emitters`` of a scene file's integrator).

    Returns
    -------
    PathLayout

    Raises
    ------
    ValueError
        Unknown kind, depth below the kind's minimum, or ``dof`` without a lens.
    """
    if kind not in KINDS:
        raise ValueError(f"unknown signal kind {kind!r}; choose one of {', '.join(KINDS)}")
    check_integer("max_depth", max_depth, -2**62)
    minimum = _minimum_depth(kind)
    if max_depth < minimum:
        raise ValueError(f"max_depth={max_depth} is too small for kind {kind!r}; it needs at least {minimum}")
    if kind == "dof" and not thin_lens:
        raise ValueError(
            "kind 'dof' needs a thin-lens camera: the scene's camera is a pinhole; "
            "give --aperture (and optionally --focus-distance)"
        )

    full = VertexPlan(next_event=True, count_emission_hit=True)
    if kind in ("path", "dof"):
        vertices = [full] * (max_depth - 1)
        count_camera_emission = not hide_emitters
    elif kind == "indirect":
        vertices = [VertexPlan(False, False)] + [full] * (max_depth - 2)
        count_camera_emission = False
    else:  # path-indirect
        vertices = [VertexPlan(False, False)] + [full] * (max_depth - 2) + [VertexPlan(False, True)]
        count_camera_emission = False

    dimensions = list(IMAGE_AXES)
    if thin_lens:
        dimensions += list(LENS_AXES)
    for index, plan in enumerate(vertices, start=1):
        dimensions += vertex_dimensions(index, plan)

    if kind == "dof":
        axes = IMAGE_AXES + LENS_AXES
    elif kind == "indirect":
        axes = IMAGE_AXES + ("bsdf1_u", "bsdf1_v")
    else:
        axes = tuple(d for d in dimensions if d in IMAGE_AXES or d.startswith(("light", "bsdf")))

    return PathLayout(
        kind=kind,
        max_depth=max_depth,
        thin_lens=thin_lens,
        count_camera_emission=count_camera_emission,
        vertices=tuple(vertices),
        dimensions=tuple(dimensions),
        axes=tuple(axes),
    )


#: Cells along each non-image axis when no shape is given (:func:`default_shape`): the lens and the
#: secondary ray's two axes 16 each, as the thesis's dof and indirect signals (7.1, 7.2: 250x250x16x16);
#: each light and BSDF dimension of a path vertex 4, as its path-space signals (5.3, 6.1: 100x100x4^8).
DEFAULT_AXIS_CELLS = {"dof": 16, "indirect": 16, "path": 4, "path-indirect": 4}


def default_shape(kind, max_depth, resolution):
    """The signal grid of ``kind`` when none is given: the film's ``(width, height)``, then
    :data:`DEFAULT_AXIS_CELLS` cells along every other axis of the kind's layout.

    Parameters
    ----------
    kind : str
        One of :data:`KINDS`.
    max_depth : int
        Longest path (Mitsuba's convention); the number of axes of ``path`` and
        ``path-indirect`` grows with it.
    resolution : tuple of int
        The film's ``(width, height)``.

    Returns
    -------
    tuple of int

    Examples
    --------
    >>> default_shape("dof", 3, (128, 96))
    (128, 96, 16, 16)
    >>> default_shape("path", 2, (64, 64))
    (64, 64, 4, 4, 4, 4)
    """
    axes = path_layout(kind, max_depth, thin_lens=True).axes  # the axes do not depend on the lens
    return tuple(int(size) for size in resolution) + (DEFAULT_AXIS_CELLS[kind],) * (len(axes) - 2)


#: The most cells a signal grid may have: kernels index cells with 32-bit integers.
MAXIMUM_GRID_CELLS = 2**32 - 1


def check_indexable_grid(grid_shape, *, advice="give a coarser --shape, or a smaller --max-depth"):
    """Refuse a signal grid whose flat cell index does not fit the kernels' 32 bits.

    A kind's default grid on a deep ``path`` layout (4 cells per axis, 4 axes
    per bounce) passes :data:`MAXIMUM_GRID_CELLS` after a few bounces: the
    samples do not depend on the grid, but a flat cell index would wrap.
    Methods that bin samples into the grid ask for cells; the others draw
    without them.

    Raises
    ------
    ValueError
        The grid has more than :data:`MAXIMUM_GRID_CELLS` cells; the message
        names the grid, its cell count and ``advice``.
    """
    shape = tuple(int(size) for size in grid_shape)
    cells = math.prod(shape)
    if cells > MAXIMUM_GRID_CELLS:
        raise ValueError(f"the signal grid {shape} has {cells:.3g} cells; at most 2**32 - 1 can be indexed "
                         f"({advice})")


def grid_strides(grid_shape):
    """Row-major strides of ``grid_shape``: a cell's flat index is ``sum(coordinate * stride)`` over the axes.

    Examples
    --------
    >>> grid_strides((4, 3, 2))
    (6, 2, 1)
    """
    strides = [1]
    for size in tuple(grid_shape)[:0:-1]:
        strides.append(strides[-1] * int(size))
    return tuple(strides[::-1])
