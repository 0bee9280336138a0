"""What a method needs of a comparison, declared and checked before anything renders.

A method lists its needs as :class:`Requirement` objects in its ``requires``
class attribute (its kinds and ``needs_resolution_multiple`` are requirements
too, :meth:`~sparselt.methods.base.Method.requirements`). The harness checks
them all against a :class:`MethodSetup` (what is known of the comparison)
twice: once from the configuration, before the scene loads (the camera of a
scene file is not known yet: a camera requirement waits), and once with the
loaded scene, before the reference renders. So ``compare --methods
pt,aaf-dof`` on a pinhole camera stops with a message naming ``aaf-dof`` and
``--aperture``, and no reference is rendered for a comparison that cannot run.

Examples
--------
>>> from sparselt.methods.preconditions import MethodSetup, ThinLens
>>> setup = MethodSetup(kind="dof", grid_shape=(16, 16, 4, 4), resolution=(16, 16), thin_lens=False)

References
----------
scikit-learn's ``_parameter_constraints`` (constraints declared, checked in one place, before fitting).
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class MethodSetup:
    """What the harness knows of a comparison when it checks the methods' requirements.

    Attributes
    ----------
    kind : str
        Signal kind.
    grid_shape : tuple of int
        The signal grid, image axes first.
    resolution : tuple of int
        Output ``(width, height)``.
    spps : tuple of int
        The budgets the method runs at (empty: unknown).
    thin_lens : bool or None
        Whether the camera is a thin lens; None before the scene has loaded
        when its camera is not known yet (a scene file).
    aperture_radius : float or None
        The thin lens's aperture radius (None: unknown).
    film_resolution : tuple of int or None
        The loaded scene's film ``(width, height)`` (None: not loaded yet).
    """

    kind: str
    grid_shape: tuple
    resolution: tuple
    spps: tuple = ()
    thin_lens: bool | None = None
    aperture_radius: float | None = None
    film_resolution: tuple | None = None

    @classmethod
    def of_context(cls, context, spps=()):
        """The setup of a :class:`~sparselt.methods.base.ComparisonContext` whose scene has loaded."""
        scene = context.scene
        thin_lens = bool(scene.camera.thin_lens) if getattr(scene, "camera", None) is not None else None
        aperture = float(scene.lens_geometry()["aperture_radius"]) if thin_lens else (0.0 if thin_lens is False
                                                                                        else None)
        film = (int(scene.width), int(scene.height)) if hasattr(scene, "width") else None
        return cls(kind=context.kind, grid_shape=tuple(context.grid_shape), resolution=tuple(context.resolution),
                   spps=tuple(spps), thin_lens=thin_lens, aperture_radius=aperture, film_resolution=film)


def tiles_of(grid_shape, tile, option, row=""):
    """``(tiles along x, tiles along y)`` of square tiles of side ``tile`` over the grid's image axes.

    Raises
    ------
    ValueError
        ``tile`` does not divide both image axes; the message names the option
        (``method.option``, and ``row`` when given) and the sides that do.
    """
    width, height = int(grid_shape[0]), int(grid_shape[1])
    if width % tile or height % tile:
        common = math.gcd(width, height)
        divisors = [divisor for divisor in range(1, common + 1) if common % divisor == 0]
        raise ValueError(f"option {option}={tile}{row} must divide both image axes of the grid {width}x{height}; "
                         f"choose one of {', '.join(map(str, divisors))}")
    return width // tile, height // tile


class Requirement:
    """One thing a method needs of the comparison; :meth:`check` raises a ValueError naming the method and the fix."""

    def describe(self):  # pragma: no cover - interface
        """What is required, in words (``sparselt methods NAME`` lists it)."""
        raise NotImplementedError

    def check(self, method, setup):  # pragma: no cover - interface
        """Raise ValueError when ``setup`` does not meet the requirement for ``method`` (an instance)."""
        raise NotImplementedError

    def __repr__(self):
        return f"{type(self).__name__}()"


class SupportedKind(Requirement):
    """The comparison's kind is one of the method's ``kinds``."""

    def describe(self):
        return "the comparison's kind among the method's kinds"

    def check(self, method, setup):
        if setup.kind not in method.kinds:
            raise ValueError(f"method {method.label!r} does not support kind {setup.kind!r}; it supports "
                             f"{', '.join(method.kinds)}")


class ResolutionMultiple(Requirement):
    """The output resolution is a multiple of the grid's image axes (each grid pixel covers whole output pixels)."""

    def describe(self):
        return "--resolution a multiple of the shape's image axes"

    def check(self, method, setup):
        if any(size % cells for size, cells in zip(setup.resolution, setup.grid_shape[:2])):
            raise ValueError(f"method {method.label!r} needs --resolution to be a multiple of the shape's image axes "
                             f"{tuple(setup.grid_shape[:2])}; got {tuple(setup.resolution)}")


class ThinLens(Requirement):
    """A thin-lens camera with an aperture (depth of field), e.g. for filters derived from circles of confusion."""

    def describe(self):
        return "a thin-lens camera (--aperture)"

    def check(self, method, setup):
        if setup.thin_lens is False or (setup.aperture_radius is not None and not setup.aperture_radius > 0):
            raise ValueError(f"method {method.label!r} needs a thin-lens camera with an aperture; the scene's camera "
                             "is a pinhole: give --aperture (and optionally --focus-distance)")


@dataclass(frozen=True, repr=True)
class TileDividesGrid(Requirement):
    """The method's option ``option`` (a tile side in grid pixels) divides both image axes of the grid."""

    option: str = "tile"

    def describe(self):
        return f"option {self.option} dividing both image axes of the grid"

    def check(self, method, setup):
        row = f" (row {method.label!r})" if method.label != method.name else ""
        tiles_of(setup.grid_shape, int(getattr(method.options, self.option)), f"{method.name}.{self.option}", row)


class FilmResolution(Requirement):
    """The output resolution is the scene's film resolution (the method renders the film itself)."""

    def describe(self):
        return "the output resolution equal to the scene's film resolution"

    def check(self, method, setup):
        if setup.film_resolution is not None and tuple(setup.film_resolution) != tuple(setup.resolution):
            width, height = setup.film_resolution
            raise ValueError(f"method {method.label!r} renders at the scene's film resolution {width}x{height}, got "
                             f"an output resolution {setup.resolution[0]}x{setup.resolution[1]}")


@dataclass(frozen=True, repr=True)
class MinimumSpp(Requirement):
    """Every budget has at least ``spp`` samples per pixel (two folds of a cross-fitted control variate: 2)."""

    spp: int = 2
    reason: str = "it splits each pixel's samples in two folds"

    def describe(self):
        return f"--spp at least {self.spp}"

    def check(self, method, setup):
        small = [spp for spp in setup.spps if spp < self.spp]
        if small:
            raise ValueError(f"method {method.label!r} needs spp >= {self.spp} ({self.reason}), got spp {small[0]}")


@dataclass(frozen=True, repr=True)
class GridMemory(Requirement):
    """The method's arrays over every cell of the signal grid fit in the memory this machine has available.

    A method that holds the whole grid densely (an importance map and its
    tables, a spectrum) needs memory in proportion to the grid's cells, not to
    the image: at the path kind's default shape (the film's pixels, then 4
    cells per path-vertex axis, ``4^8`` per pixel at depth 3) a 256x256 film is
    4.3 billion cells. ``bytes_per_cell`` is the method's measured peak over
    PT's per cell (``docs/experiments/README.md``, issue 37's eighteenth
    session); the comparison is refused before anything renders when that
    times the cells exceeds :func:`~sparselt.measurement.available_memory`
    (a run beyond it was killed by the system, or swapped for minutes).
    """

    bytes_per_cell: float

    def describe(self):
        return f"about {self.bytes_per_cell:g} bytes per grid cell (--shape) within the available memory"

    def check(self, method, setup):
        from ..measurement import available_memory

        cells = math.prod(int(size) for size in setup.grid_shape)
        needed = cells * float(self.bytes_per_cell)
        available = available_memory()
        if needed > available:
            shape = "x".join(str(int(size)) for size in setup.grid_shape)
            largest = max(1, int(available // float(self.bytes_per_cell)))
            suggestion = coarser_shape(setup.grid_shape, largest)
            hint = f", e.g. --shape {','.join(str(size) for size in suggestion)}" if suggestion else ""
            raise ValueError(f"method {method.label!r} holds arrays over every cell of the grid {shape} "
                             f"({cells:,} cells, about {self.bytes_per_cell:g} bytes each): {needed / 2**30:.1f} GiB, "
                             f"more than the {available / 2**30:.1f} GiB this machine has available; give a coarser "
                             f"--shape (fewer cells per non-image axis, or fewer image cells with --resolution a "
                             f"multiple of them) of at most {largest:,} cells{hint}")


def coarser_shape(grid_shape, largest):
    """The grid with its image axes kept and every other axis at the largest common count (at most its own) whose
    cells are at most ``largest``; None where even one cell per other axis is too many."""
    image, rest = [int(size) for size in grid_shape[:2]], [int(size) for size in grid_shape[2:]]
    for count in range(max(rest, default=1), 0, -1):
        shape = image + [min(size, count) for size in rest]
        if math.prod(shape) <= largest:
            return tuple(shape)
    return None


__all__ = ["FilmResolution", "GridMemory", "MethodSetup", "MinimumSpp", "Requirement", "ResolutionMultiple",
           "SupportedKind", "ThinLens", "TileDividesGrid", "tiles_of"]
