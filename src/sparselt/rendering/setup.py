"""A scene set up once: what every command and experiment renders (issue 34).

:class:`SceneSetup` is the one place where a scene name or XML file, its
``-D`` parameters, a lens override, the signal kind, the grid shape, the
longest path and the Mitsuba variant become a resolved scene: the
:class:`~sparselt.rendering.scenes.SceneSpec` with parameters and lens
applied, its content identity (:func:`~sparselt.rendering.identity.scene_identity`),
its primary-sample-space layout and the checks that they fit together. A
command builds one, validates it before any work, and loads it in the renderer
once (:meth:`SceneSetup.load`); identities and cache keys take its
:meth:`SceneSetup.record` and its scene digest.

This module is plain Python; only :meth:`SceneSetup.load` imports the renderer.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

from ..checks import check_integer
from ..digest import digest
from .layout import KINDS, check_indexable_grid, default_shape, path_layout
from .mitsuba.runtime import DEFAULT_VARIANT, SUPPORTED_VARIANTS  # plain constants: imports no Mitsuba
from .scenes import SUPPORTED_SENSOR_TYPES, SceneSpec, get_scene, note_once, unsupported_sensor_message

#: Longest path (Mitsuba's convention) when none is given: one indirect bounce, as the thesis.
DEFAULT_MAX_DEPTH = 3


@dataclass(frozen=True)
class SceneSetup:
    """A scene, its parameters and lens, and the signal it is rendered into.

    Attributes
    ----------
    scene : str
        A built-in scene's name (``sparselt scenes``) or a Mitsuba XML file.
    kind : str or None
        Signal kind (:data:`~sparselt.rendering.layout.KINDS`); None for a
        command that renders images only (``render``).
    shape : tuple of int or None
        Signal grid, image axes first. None: :func:`~sparselt.rendering.layout.default_shape`,
        the film's resolution and the kind's default cells along the other axes
        (:attr:`grid_shape` is the one used, and :meth:`record` records it).
    max_depth : int
        Longest path, Mitsuba's convention.
    parameters : tuple of (str, str)
        Values of a scene file's ``$name`` parameters (``-D name=value``); kept sorted.
    aperture, focus_distance : float or None
        Thin-lens override of the scene's camera.
    variant : str
        Mitsuba variant (:data:`SUPPORTED_VARIANTS`).
    scene_spec : SceneSpec or None
        A programmatic scene instead of a name (its identity is its description);
        ``scene`` then only names it.
    """

    scene: str
    kind: str | None = None
    shape: tuple | None = None
    max_depth: int = DEFAULT_MAX_DEPTH
    parameters: tuple = ()
    aperture: float | None = None
    focus_distance: float | None = None
    variant: str = DEFAULT_VARIANT
    scene_spec: SceneSpec | None = field(default=None, compare=False, repr=False)

    def __post_init__(self):
        if self.shape is not None and not isinstance(self.shape, tuple):
            object.__setattr__(self, "shape", tuple(self.shape))
        pairs = tuple(self.parameters.items()) if isinstance(self.parameters, dict) else tuple(self.parameters)
        object.__setattr__(self, "parameters", tuple(sorted(tuple(pair) for pair in pairs)))

    # ----------------------------------------------------------------- resolution (no renderer)
    @cached_property
    def spec(self):
        """The :class:`SceneSpec` with the ``-D`` parameters and the lens override applied.

        Raises
        ------
        ValueError
            An unknown scene name, a missing file, a bad parameter, a
            scene file whose first sensor sparselt cannot sample (its XML
            type), a focus distance without a lens.
        """
        if self.scene_spec is not None and not isinstance(self.scene_spec, SceneSpec):
            raise TypeError(f"scene_spec must be a SceneSpec, got {type(self.scene_spec).__name__}")
        spec = self.scene_spec if self.scene_spec is not None else get_scene(self.scene)
        spec = spec.with_parameters(self.parameters)
        if spec.sensor_type is not None and spec.sensor_type not in SUPPORTED_SENSOR_TYPES:
            # Named from the XML before anything loads or any other check of the film (a radiance meter's 1x1
            # film was refused first as too small for SSIM, its sensor only once that was fixed).
            raise ValueError(f"scene file {spec.filename!r}: " + unsupported_sensor_message(spec.sensor_type))
        return spec.with_lens(self.aperture, self.focus_distance)

    @cached_property
    def scene_identity(self):
        """The scene's content identity (:func:`~sparselt.rendering.identity.scene_identity`): files, parameters, lens."""
        from .identity import scene_identity

        return scene_identity(self.spec)

    @property
    def film_resolution(self):
        """The scene's own ``(width, height)``: a scene file's film, a built-in scene's default."""
        return tuple(self.spec.default_resolution)

    @property
    def grid_shape(self):
        """The signal grid: :attr:`shape`, or the kind's default on the film's resolution."""
        if self.shape is not None:
            return tuple(self.shape)
        if self.kind is None:
            raise ValueError("a scene setup without a kind has no signal grid")
        return default_shape(self.kind, self.max_depth, self.film_resolution)

    def layout(self, thin_lens=None):
        """The kind's :class:`~sparselt.rendering.layout.PathLayout` for a camera with or without a lens.

        ``thin_lens`` None: the scene's camera decides (a built-in scene's
        camera is known before loading; a scene file's is read by the renderer,
        see :meth:`load`).

        Raises
        ------
        ValueError
            ``dof`` on a pinhole camera, a depth below the kind's minimum, or a
            shape whose number of axes is not the kind's.
        """
        if thin_lens is None:
            thin_lens = self.spec.resolved_camera().thin_lens
        layout = path_layout(self.kind, self.max_depth, thin_lens=thin_lens, hide_emitters=self.spec.hide_emitters)
        shape = self.grid_shape
        if len(shape) != len(layout.axes):
            raise ValueError(f"shape {shape} has {len(shape)} axes but kind {self.kind!r} at max depth "
                             f"{self.max_depth} has {len(layout.axes)}: {', '.join(layout.axes)}")
        return layout

    def check_values(self):
        """The checks that need not even resolve the scene: kind, depth, variant, shape; return ``self``.

        Raises
        ------
        ValueError
            Unknown kind or variant; a depth below 1; a shape entry below 1,
            fewer than the two image axes, or 2**32 cells or more.
        TypeError
            A value of the wrong type.
        """
        if self.kind is not None and self.kind not in KINDS:
            raise ValueError(f"unknown signal kind {self.kind!r}; choose one of {', '.join(KINDS)}")
        check_integer("max_depth", self.max_depth, 1)
        if self.variant not in SUPPORTED_VARIANTS:
            raise ValueError(f"unknown Mitsuba variant {self.variant!r}; choose one of {', '.join(SUPPORTED_VARIANTS)}")
        if self.shape is not None:
            if len(self.shape) < 2:
                raise ValueError(f"shape {self.shape} needs at least the two image-plane axes")
            for size in self.shape:
                check_integer("every shape entry", size, 1)
            check_indexable_grid(self.shape, advice="give a coarser --shape")
        return self

    def validate(self):
        """Check everything that needs no renderer; return ``self``.

        Raises
        ------
        ValueError
            As :meth:`check_values`; and an unknown scene, a number of axes
            that is not the kind's, ``dof`` on a built-in pinhole camera, a
            bad ``-D`` parameter or lens.
        TypeError
            A value of the wrong type.
        """
        self.check_values()
        spec = self.spec
        if self.kind is not None:
            if spec.camera is not None:
                self.layout()
            else:  # a scene file's camera is read when it loads; the number of axes is known already
                self.layout(thin_lens=True)
        return self

    # ----------------------------------------------------------------- identity
    def record(self):
        """What identifies the setup in a folder's identity or a cache key: every field, the shape resolved.

        ``shape_given`` tells whether the grid was given or the kind's default
        on the film's resolution.
        """
        return {"scene": self.scene, "kind": self.kind,
                "shape": list(self.grid_shape) if self.kind is not None else None,
                "shape_given": self.shape is not None, "max_depth": self.max_depth,
                "scene_parameters": [list(pair) for pair in self.parameters], "aperture": self.aperture,
                "focus_distance": self.focus_distance, "variant": self.variant}

    def digest(self):
        """The :func:`~sparselt.digest.digest` of :meth:`record` with the scene's content digest."""
        return digest({"setup": self.record(), "scene": self.scene_identity["digest"]})

    # ----------------------------------------------------------------- loading (the renderer)
    def load(self, resolution=None):
        """Load the scene in the renderer once; return a :class:`LoadedScene`.

        Parameters
        ----------
        resolution : tuple of int, optional
            Film ``(width, height)``; default the grid's image axes (or the
            film's own resolution for a setup without a kind).

        Raises
        ------
        ValueError
            As :meth:`layout`, now that a scene file's camera is known.
        """
        from .mitsuba import MitsubaScene

        if resolution is None:
            resolution = self.grid_shape[:2] if self.kind is not None else self.film_resolution
        scene = MitsubaScene(self.spec, tuple(resolution), variant=self.variant)
        layout = self.layout(scene.camera.thin_lens) if self.kind is not None else None
        if layout is not None and self.spec.filename is not None:
            self._note_the_files_depth()
        return LoadedScene(setup=self, scene=scene, layout=layout)

    def _note_the_files_depth(self):
        """Say once per file and depth when the file's integrator names another ``max_depth`` than the one this
        kind renders to (every method, PT and the reference use :attr:`max_depth`; the file's integrator is not
        run)."""
        files_depth = self.spec.integrator_max_depth
        if files_depth is None or files_depth == self.max_depth:
            return
        theirs = "no depth limit (max_depth -1)" if files_depth < 0 else f"max_depth {files_depth}"
        advice = "" if files_depth < 0 else f": give --max-depth {files_depth} (max_depth in a suite) to match"
        note_once(self.spec.filename, ("depth", files_depth, self.max_depth),
                  f"the integrator of {self.spec.name!r} has {theirs}; the {self.kind!r} kind here renders paths "
                  f"up to max depth {self.max_depth} (every method, PT and the reference alike){advice}")


@dataclass(frozen=True)
class LoadedScene:
    """A :class:`SceneSetup` loaded in the renderer: the renderer's scene and the kind's layout."""

    setup: SceneSetup
    scene: object
    layout: object

    @property
    def thin_lens(self):
        """Whether the loaded camera is a thin lens (a scene file's camera is known only once it has loaded)."""
        return bool(self.scene.camera.thin_lens)


__all__ = ["DEFAULT_MAX_DEPTH", "DEFAULT_VARIANT", "LoadedScene", "SUPPORTED_VARIANTS", "SceneSetup"]
