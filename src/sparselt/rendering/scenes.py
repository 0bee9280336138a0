"""Scenes, described in plain Python so that nothing but the adapter imports Mitsuba.

A scene is a :class:`SceneSpec`: the Mitsuba scene dictionary *without* a
sensor (shapes, BSDFs, emitters; transforms given as :class:`Transform`
chains) plus a :class:`Camera`. The renderer adapter turns a spec into Mitsuba
objects and builds the sensor itself, with the film resolution set by the
signal's image axes and a box pixel filter, so that image-plane cell ``i`` is
exactly pixel ``i``. A scene file given by path is loaded by Mitsuba and its
first sensor is read back into a :class:`Camera`.

Built-in scenes (``sparselt scenes`` lists them):

``cornell-box``
    Exactly Mitsuba's ``mi.cornell_box()``; only the pixel filter (box instead
    of Gaussian) and the resolution differ.
``cornell-caustics``
    The same box with a metal (conductor) sphere and a glass (dielectric)
    sphere.
Procedural scenes registered by :mod:`sparselt.rendering.procedural`.
"""

from __future__ import annotations

import math
import os
import re
import sys
from dataclasses import dataclass, field, replace
from typing import Callable


@dataclass(frozen=True)
class Transform:
    """A chain of affine operations, composed left to right as in Mitsuba.

    ``Transform().translate(t).rotate(axis, angle).scale(s)`` builds the same
    matrix as ``mi.ScalarTransform4f().translate(t).rotate(axis, angle).scale(s)``:
    the adapter replays the chain with Mitsuba's own functions.
    """

    operations: tuple = ()

    def _then(self, *operation):
        return Transform(self.operations + (operation,))

    def translate(self, offset):
        return self._then("translate", tuple(float(v) for v in offset))

    def rotate(self, axis, angle_degrees):
        return self._then("rotate", tuple(float(v) for v in axis), float(angle_degrees))

    def scale(self, factor):
        if isinstance(factor, (int, float)):
            factor = (factor, factor, factor)
        return self._then("scale", tuple(float(v) for v in factor))

    def look_at(self, origin, target, up):
        return self._then(
            "look_at", tuple(map(float, origin)), tuple(map(float, target)), tuple(map(float, up))
        )

    def matrix(self, rows):
        """Multiply by an explicit 4x4 matrix given as nested rows."""
        return self._then("matrix", tuple(tuple(float(v) for v in row) for row in rows))


@dataclass(frozen=True)
class Camera:
    """A perspective or thin-lens camera.

    Attributes
    ----------
    to_world : Transform
        Camera-to-world transform (Mitsuba convention, looking along +z).
    fov : float
        Field of view in degrees along ``fov_axis``.
    fov_axis : str
        Mitsuba's ``fov_axis`` ('x', 'y', 'smaller', 'larger', 'diagonal').
    near_clip, far_clip : float
        Clip distances.
    aperture_radius : float or None
        Lens radius; ``None`` for a pinhole camera.
    focus_distance : float
        Distance of the plane in focus (ignored by a pinhole camera).
    """

    to_world: Transform
    fov: float
    fov_axis: str = "x"
    near_clip: float = 0.001
    far_clip: float = 1000.0
    aperture_radius: float | None = None
    focus_distance: float = 1000.0

    @property
    def thin_lens(self):
        return self.aperture_radius is not None

    def with_lens(self, aperture_radius=None, focus_distance=None):
        """Return a copy with a thin lens (or a changed focus distance).

        Raises
        ------
        ValueError
            Non-positive aperture or focus distance.
        """
        camera = self
        if aperture_radius is not None:
            if not (aperture_radius > 0 and math.isfinite(aperture_radius)):
                raise ValueError(f"aperture radius must be a positive finite number, got {aperture_radius!r}")
            camera = replace(camera, aperture_radius=float(aperture_radius))
        if focus_distance is not None:
            if not (focus_distance > 0 and math.isfinite(focus_distance)):
                raise ValueError(f"focus distance must be a positive finite number, got {focus_distance!r}")
            if camera.aperture_radius is None:
                raise ValueError("--focus-distance needs a thin-lens camera: give --aperture as well")
            camera = replace(camera, focus_distance=float(focus_distance))
        return camera


@dataclass(frozen=True)
class SceneSpec:
    """Everything but the sensor, plus the camera.

    Exactly one of ``objects`` (a Mitsuba scene dictionary without sensor and
    integrator) and ``filename`` (a Mitsuba XML file) is set. ``camera`` is
    ``None`` for a file until the adapter has read the file's sensor.
    ``parameters`` are the values of the file's ``$name`` parameters
    (Mitsuba's ``-D name=value``), sorted ``(name, value)`` string pairs.
    ``integrator_max_depth`` is the file integrator's ``max_depth`` (None
    where it names none, and for built-in scenes): sparselt renders each kind
    to its own depth and only notes a difference.
    """

    name: str
    description: str
    objects: dict | None = None
    filename: str | None = None
    camera: Camera | None = None
    default_resolution: tuple = (256, 256)
    lens_overrides: dict = field(default_factory=dict)
    hide_emitters: bool = False
    parameters: tuple = ()
    integrator_max_depth: int | None = None
    sensor_type: str | None = None

    def with_parameters(self, parameters):
        """Return a copy with values for the XML file's ``$name`` parameters (later values win).

        Parameters
        ----------
        parameters : sequence of (str, str) or dict
            ``(name, value)`` pairs, as ``-D name=value`` gives them; numbers
            are written as text.

        Raises
        ------
        ValueError
            Parameters for a built-in scene (it has none), a name that is not
            an identifier or that Mitsuba's ``load_file`` reserves.
        TypeError
            A value that is not text or a number.
        """
        pairs = tuple(parameters.items()) if isinstance(parameters, dict) else tuple(parameters)
        if not pairs:
            return self
        if self.filename is None:
            names = ", ".join(str(pair[0]) for pair in pairs)
            raise ValueError(f"scene {self.name!r} is built in and takes no parameters (got {names}); -D name=value "
                             "sets the $name parameters of a Mitsuba XML scene file")
        values = dict(self.parameters)
        for pair in pairs:
            if len(pair) != 2:
                raise ValueError(f"a scene parameter is a (name, value) pair, got {pair!r}")
            name, value = pair
            if not isinstance(name, str) or not PARAMETER_NAME.fullmatch(name):
                raise ValueError(f"scene parameter name {name!r} is not a name (letters, digits and _, not starting "
                                 "with a digit)")
            if name in RESERVED_PARAMETERS:
                raise ValueError(f"scene parameter name {name!r} is reserved by Mitsuba's load_file "
                                 f"({', '.join(RESERVED_PARAMETERS)}); rename the parameter in the XML file")
            if isinstance(value, bool) or not isinstance(value, (str, int, float)):
                raise TypeError(f"scene parameter {name!r} must be text or a number, got {type(value).__name__}")
            values[name] = str(value)
        spec = replace(self, parameters=tuple(sorted(values.items())))
        settings = read_xml_settings(self.filename, spec.parameters)
        return replace(spec, default_resolution=settings["resolution"] or self.default_resolution,
                       hide_emitters=settings["hide_emitters"], integrator_max_depth=settings["max_depth"],
                       sensor_type=settings["sensor_type"])

    def with_lens(self, aperture_radius=None, focus_distance=None):
        """Record a thin-lens override; applied to the camera once it is known."""
        overrides = dict(self.lens_overrides)
        if aperture_radius is not None:
            overrides["aperture_radius"] = aperture_radius
        if focus_distance is not None:
            overrides["focus_distance"] = focus_distance
        spec = replace(self, lens_overrides=overrides)
        if spec.camera is not None:
            spec.resolved_camera()  # validate now
        return spec

    def resolved_camera(self, camera=None):
        """The camera with the lens overrides applied.

        A pinhole camera given an aperture without a focus distance keeps its
        own focus distance here; the renderer adapter then focuses it where
        the central ray hits the scene (see :meth:`focuses_on_the_scene`).
        """
        camera = camera or self.camera
        if camera is None:
            raise ValueError(f"scene {self.name!r} has no camera yet (a file scene is read by the adapter)")
        return camera.with_lens(**self.lens_overrides)

    def focuses_on_the_scene(self, camera=None):
        """Whether the lens overrides make a pinhole ``camera`` a thin lens without saying where it focuses.

        Then the focus distance is the distance at which the camera's central
        ray hits the scene (the renderer adapter casts it); a thin-lens
        camera keeps its own focus distance.
        """
        camera = camera or self.camera
        return ("aperture_radius" in self.lens_overrides and "focus_distance" not in self.lens_overrides
                and camera is not None and not camera.thin_lens)


# ---------------------------------------------------------------------------
# Built-in scenes
# ---------------------------------------------------------------------------

SCENES: dict[str, Callable[[], SceneSpec]] = {}
PARAMETER_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
RESERVED_PARAMETERS = ("path", "parallel", "optimize")  # keyword arguments of mi.load_file itself


def register(name):
    """Decorator: register a function returning a :class:`SceneSpec` under ``name``."""

    def decorate(function):
        SCENES[name] = function
        return function

    return decorate


def _rgb(value):
    return {"type": "rgb", "value": list(value)}


def cornell_box_objects():
    """The objects of ``mi.cornell_box()`` (Mitsuba 3.9), sensor and integrator removed."""
    T = Transform
    white = {"type": "ref", "id": "white"}
    return {
        "type": "scene",
        "white": {"type": "diffuse", "reflectance": _rgb([0.885809, 0.698859, 0.666422])},
        "green": {"type": "diffuse", "reflectance": _rgb([0.105421, 0.37798, 0.076425])},
        "red": {"type": "diffuse", "reflectance": _rgb([0.570068, 0.0430135, 0.0443706])},
        "light": {
            "type": "rectangle",
            "to_world": T().translate([0.0, 0.99, 0.01]).rotate([1, 0, 0], 90).scale([0.23, 0.19, 0.19]),
            "bsdf": dict(white),
            "emitter": {"type": "area", "radiance": _rgb([18.387, 13.9873, 6.75357])},
        },
        "floor": {"type": "rectangle", "to_world": T().translate([0.0, -1.0, 0.0]).rotate([1, 0, 0], -90), "bsdf": dict(white)},
        "ceiling": {"type": "rectangle", "to_world": T().translate([0.0, 1.0, 0.0]).rotate([1, 0, 0], 90), "bsdf": dict(white)},
        "back": {"type": "rectangle", "to_world": T().translate([0.0, 0.0, -1.0]), "bsdf": dict(white)},
        "green-wall": {
            "type": "rectangle",
            "to_world": T().translate([1.0, 0.0, 0.0]).rotate([0, 1, 0], -90),
            "bsdf": {"type": "ref", "id": "green"},
        },
        "red-wall": {
            "type": "rectangle",
            "to_world": T().translate([-1.0, 0.0, 0.0]).rotate([0, 1, 0], 90),
            "bsdf": {"type": "ref", "id": "red"},
        },
        "small-box": {
            "type": "cube",
            "to_world": T().translate([0.335, -0.7, 0.38]).rotate([0, 1, 0], -17).scale(0.3),
            "bsdf": dict(white),
        },
        "large-box": {
            "type": "cube",
            "to_world": T().translate([-0.33, -0.4, -0.28]).rotate([0, 1, 0], 18.25).scale([0.3, 0.61, 0.3]),
            "bsdf": dict(white),
        },
    }


def cornell_box_camera():
    """The camera of ``mi.cornell_box()``."""
    return Camera(
        to_world=Transform().look_at([0, 0, 3.90], [0, 0, 0], [0, 1, 0]),
        fov=39.3077,
        fov_axis="smaller",
        near_clip=0.001,
        far_clip=100.0,
        focus_distance=1000.0,
    )


@register("cornell-box")
def cornell_box():
    return SceneSpec(
        name="cornell-box",
        description="Mitsuba's built-in Cornell box (mi.cornell_box()) with a box pixel filter",
        objects=cornell_box_objects(),
        camera=cornell_box_camera(),
    )


@register("cornell-caustics")
def cornell_caustics():
    objects = cornell_box_objects()
    # The two boxes make room for a metal and a glass sphere; the metal sphere's
    # caustic on the floor is a light -> metal -> floor -> camera path (depth 3).
    del objects["small-box"], objects["large-box"]
    objects["metal-sphere"] = {
        "type": "sphere",
        "center": [-0.42, -0.62, -0.25],
        "radius": 0.38,
        "bsdf": {"type": "conductor", "material": "Au"},
    }
    objects["glass-sphere"] = {
        "type": "sphere",
        "center": [0.42, -0.65, 0.3],
        "radius": 0.35,
        "bsdf": {"type": "dielectric", "int_ior": "bk7", "ext_ior": "air"},
    }
    return SceneSpec(
        name="cornell-caustics",
        description="Cornell box with a gold sphere (caustic reachable at depth 3) and a glass sphere",
        objects=objects,
        camera=cornell_box_camera(),
    )


def scene_names():
    """Names of the built-in scenes, sorted."""
    _load_procedural()
    return sorted(SCENES)


#: The Mitsuba sensor types whose image plane and lens sparselt samples.
SUPPORTED_SENSOR_TYPES = ("perspective", "thinlens")


def unsupported_sensor_message(sensor_type):
    """Why a scene whose sensor is of ``sensor_type`` (not in :data:`SUPPORTED_SENSOR_TYPES`) is refused."""
    return (f"the scene's sensor is of type {sensor_type!r}, not a perspective or thin-lens camera; sparselt "
            "samples the image plane and lens of those only: change the XML's <sensor type=...> to "
            "'perspective' or 'thinlens'")


def read_xml_settings(path, parameters=()):
    """What sparselt takes from a Mitsuba XML file besides the scene: film size, ``hide_emitters``, the
    integrator's ``max_depth`` (only to note a difference from the kind's depth) and the sensor's type.

    Returns ``{'resolution': (width, height) or None, 'hide_emitters': bool, 'max_depth': int or None,
    'sensor_type': str or None}``, resolving ``$name`` references to
    ``parameters`` (``(name, value)`` pairs) or else the file's
    ``<default>`` values. ``sensor_type`` is the first ``<sensor>``'s, None
    where the file has none or includes other files (an included sensor may
    come first). Plain XML parsing: the renderer is not needed.
    """
    import xml.etree.ElementTree as ElementTree

    try:
        root = ElementTree.parse(path).getroot()
    except ElementTree.ParseError as error:
        raise ValueError(f"scene file {path!r} is not valid XML: {error}") from None
    defaults = {node.get("name"): node.get("value") for node in root.iter("default")}
    defaults.update(dict(parameters))

    def resolved(text):
        return defaults.get(text[1:], text) if text.startswith("$") else text

    def value(node):
        return resolved(node.get("value", ""))

    settings = {"resolution": None, "hide_emitters": False, "max_depth": None, "sensor_type": None}
    sensor = next(root.iter("sensor"), None)
    if sensor is not None and next(root.iter("include"), None) is None:
        settings["sensor_type"] = resolved(sensor.get("type", ""))
    for film in root.iter("film"):
        sizes = {node.get("name"): value(node) for node in film.findall("integer")}
        try:
            settings["resolution"] = (int(sizes["width"]), int(sizes["height"]))
        except (KeyError, ValueError):
            pass
        break
    for integrator in root.iter("integrator"):
        for node in integrator.iter("boolean"):
            if node.get("name") == "hide_emitters":
                settings["hide_emitters"] = value(node).strip().lower() == "true"
        for node in integrator.iter("integer"):
            if node.get("name") == "max_depth" and settings["max_depth"] is None:
                try:
                    settings["max_depth"] = int(value(node))
                except ValueError:
                    pass
    return settings


#: (scene file, topic) pairs already noted on standard error (once per file and process).
_NOTED = set()


def note_once(filename, topic, message):
    """Print ``message`` as a note on standard error, once per scene file and ``topic`` in a process."""
    if (filename, topic) in _NOTED:
        return
    _NOTED.add((filename, topic))
    print(f"sparselt: note: {message}", file=sys.stderr)


def _load_procedural():
    from . import procedural  # noqa: F401  (registers its scenes)
    from . import standard_scenes  # noqa: F401  (registers the standard benchmark scenes)


def get_scene(name_or_path):
    """Return the :class:`SceneSpec` for a built-in name or a Mitsuba XML file path.

    Raises
    ------
    ValueError
        The name is neither a built-in scene nor an existing ``.xml`` file.
    """
    _load_procedural()
    if name_or_path in SCENES:
        return SCENES[name_or_path]()
    if str(name_or_path).lower().endswith(".xml"):
        if not os.path.isfile(name_or_path):
            raise ValueError(f"scene file {name_or_path!r} does not exist")
        path = os.path.abspath(name_or_path)
        settings = read_xml_settings(path)
        return SceneSpec(name=os.path.basename(path), description=f"Mitsuba scene file {path}", filename=path,
                         default_resolution=settings["resolution"] or (256, 256),
                         hide_emitters=settings["hide_emitters"], integrator_max_depth=settings["max_depth"],
                         sensor_type=settings["sensor_type"])
    raise ValueError(
        f"unknown scene {name_or_path!r}; built-in scenes are: {', '.join(sorted(SCENES))}; "
        "or give the path of a Mitsuba 3 XML scene file"
    )
