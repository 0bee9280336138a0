"""Scenes and cameras in Mitsuba's terms: transforms, scene and sensor dictionaries, scene files.

A :class:`~sparselt.rendering.scenes.SceneSpec` is plain Python; these
functions turn it into the dictionaries :func:`mitsuba.load_dict` takes, read
a loaded sensor back into a :class:`~sparselt.rendering.scenes.Camera`, and
load a scene file with its ``$name`` parameters.
"""

from __future__ import annotations

import os
import re

import numpy as np

from ..scenes import Camera, Transform, unsupported_sensor_message
from .runtime import modules


def to_mitsuba_transform(transform):
    """Replay a :class:`Transform` chain with ``mi.ScalarTransform4f``."""
    mi, _ = modules()
    result = mi.ScalarTransform4f()
    for operation in transform.operations:
        name, arguments = operation[0], operation[1:]
        if name == "translate":
            result = result.translate(list(arguments[0]))
        elif name == "rotate":
            result = result.rotate(list(arguments[0]), arguments[1])
        elif name == "scale":
            result = result.scale(list(arguments[0]))
        elif name == "look_at":
            result = result.look_at(origin=list(arguments[0]), target=list(arguments[1]), up=list(arguments[2]))
        elif name == "matrix":
            result = result @ mi.ScalarTransform4f([list(row) for row in arguments[0]])
        else:
            raise ValueError(f"unknown transform operation {name!r}")
    return result


def to_mitsuba_dict(value):
    """Recursively replace :class:`Transform` objects by Mitsuba transforms."""
    if isinstance(value, Transform):
        return to_mitsuba_transform(value)
    if isinstance(value, dict):
        return {key: to_mitsuba_dict(item) for key, item in value.items()}
    if isinstance(value, list):
        return [to_mitsuba_dict(item) for item in value]
    return value


def sensor_dictionary(camera, width, height, *, principal_point=(0.0, 0.0)):
    """Mitsuba sensor dictionary for ``camera`` with a box-filtered float film.

    ``principal_point``: the image centre's offset as a fraction of the film
    (Mitsuba's ``principal_point_offset_x``, ``_y``), for a pinhole camera
    only (Mitsuba's ``thinlens`` has none).
    """
    sensor = {
        "type": "thinlens" if camera.thin_lens else "perspective",
        "fov": camera.fov,
        "fov_axis": camera.fov_axis,
        "near_clip": camera.near_clip,
        "far_clip": camera.far_clip,
        "to_world": to_mitsuba_transform(camera.to_world),
        "sampler": {"type": "independent", "sample_count": 1},
        "film": {
            "type": "hdrfilm",
            "width": int(width),
            "height": int(height),
            "rfilter": {"type": "box"},
            "pixel_format": "rgb",
            "component_format": "float32",
        },
    }
    if camera.thin_lens and any(principal_point):
        raise ValueError(f"a thin lens has no principal point offset (got {tuple(principal_point)})")
    if camera.thin_lens:
        sensor["aperture_radius"] = camera.aperture_radius
    elif any(principal_point):
        sensor["principal_point_offset_x"], sensor["principal_point_offset_y"] = (float(v) for v in principal_point)
    sensor["focus_distance"] = camera.focus_distance
    return sensor


# Mitsuba's class names of its sensor plugins -> the plugin type an XML file names.
_SENSOR_TYPES = {"PerspectiveCamera": "perspective", "ThinLensCamera": "thinlens", "IrradianceMeter": "irradiancemeter",
                 "RadianceMeter": "radiancemeter", "DistantSensor": "distant", "BatchSensor": "batch",
                 "OrthographicCamera": "orthographic"}


#: Widest lens (aperture radius over focus distance) whose camera rays are traced as coherent packets.
COHERENT_LENS_ANGLE = 0.025


def coherent_camera_rays(camera):
    """Whether camera rays are traced in Embree's coherent mode, as Mitsuba's own integrators trace them.

    Every sampler here runs a pixel's (or a cell's) lanes side by side, so
    neighbouring lanes' camera rays are neighbours, unless a wide lens
    spreads each pixel's bundle. Measured in issue 24 (PSS sampling against
    Mitsuba's ``path``, 64x64, depth 3): coherent mode makes the pinhole
    cornell-box 10-13% faster, the courtyard 5-8%, and both behind a lens of
    radius 0.05 at focus 4 (angle 0.0125) 5-10% faster, but dof-sculptures'
    lens (0.32 at 6.67, angle 0.048) 5-13% slower. The mode changes no hit
    on the procedural scenes; on the courtyard's meshes a few grazing rays
    in 10^4-10^5 hit another triangle of the same edge (Embree's packet and
    single-ray tests round differently), as in Mitsuba's own renders.
    """
    if not camera.thin_lens:
        return True
    return float(camera.aperture_radius) / float(camera.focus_distance) < COHERENT_LENS_ANGLE


def sensor_type(sensor):
    """The plugin type of a loaded Mitsuba sensor as an XML file names it (``'irradiancemeter'``), or its class name."""
    try:
        name = sensor.class_name()
    except Exception:  # noqa: BLE001  (older Mitsuba: the class name starts the description)
        name = str(sensor).split("[", 1)[0].strip()
    return _SENSOR_TYPES.get(name, name)


def _parameter_reader(sensor):
    """``read(key, default)``: a loaded sensor's scalar parameter ``key`` (Mitsuba's ``traverse``), or ``default``
    where the sensor has none."""
    mi, _ = modules()
    parameters = mi.traverse(sensor)
    keys = set(parameters.keys())

    def read(key, default):
        return float(np.ravel(np.asarray(parameters[key]))[0]) if key in keys else default

    return read


def principal_point_offset(sensor):
    """A loaded perspective sensor's principal point offset ``(x, y)`` (fractions of the film; ``(0, 0)`` where the
    sensor has none)."""
    read = _parameter_reader(sensor)
    return read("principal_point_offset_x", 0.0), read("principal_point_offset_y", 0.0)


def camera_from_sensor(sensor):
    """Read a loaded Mitsuba perspective or thin-lens sensor back into a :class:`Camera`."""
    matrix = np.array(sensor.world_transform().matrix, dtype=np.float64).reshape(4, 4)
    read = _parameter_reader(sensor)

    fov = read("x_fov", None)
    if fov is None:
        raise ValueError(unsupported_sensor_message(sensor_type(sensor)))
    aperture = read("aperture_radius", None)
    focus = read("focus_distance", 1000.0)
    near = read("near_clip", 0.001)
    far = read("far_clip", 1000.0)
    return Camera(
        to_world=Transform().matrix(matrix.tolist()),
        fov=fov,
        fov_axis="x",
        near_clip=near,
        far_clip=far,
        aperture_radius=aperture if aperture else None,
        focus_distance=focus,
    )


_UNDEFINED_PARAMETER = re.compile(r"undefined parameter: \$?([A-Za-z0-9_]+)")


def load_scene_file(spec):
    """Load ``spec``'s XML file with its ``$name`` parameters, its referenced files checked first.

    Raises
    ------
    ValueError
        A referenced file is missing or not of its element's type
        (:func:`~sparselt.rendering.identity.check_xml_references`), the
        file uses a parameter that has no value (the message shows ``-D``),
        or it has participating media (:func:`refuse_media`).
    """
    from ..identity import check_xml_references

    mi, _ = modules()
    check_xml_references(spec.filename, spec.parameters)
    mi.file_resolver().prepend(os.path.dirname(spec.filename))
    try:
        scene = mi.load_file(spec.filename, **dict(spec.parameters))
    except RuntimeError as error:
        match = _UNDEFINED_PARAMETER.search(str(error))
        if match is None:
            raise
        name = match.group(1)
        where = re.sub(r"^\[[^]]*\]\s*", "", str(error).strip())
        raise ValueError(f"scene {spec.name!r} uses parameter ${name} without a default; pass it as -D {name}=VALUE "
                         f"(Mitsuba: {where})") from None
    refuse_media(scene, spec.filename)
    return scene


def refuse_media(scene, filename):
    """Refuse a loaded scene with participating media (a shape's interior or exterior medium, a sensor's medium).

    sparselt's estimators, and Mitsuba's ``path`` integrator its baseline and
    references use, trace surfaces only: a medium would be ignored by every
    image of a comparison alike, so its verdicts would be about another scene
    than the file describes (found with a smoke-filled glass sphere, which
    every method rendered as clear glass).

    Raises
    ------
    ValueError
        Naming the file, the first element with a medium, and what to do.
    """
    def name(kind, item):  # its id, or its plugin class ("a Sphere")
        return f"{kind} {item.id()!r}" if item.id() else f"a {str(item).split('[', 1)[0].strip() or kind}"

    holders = [name("shape", shape) for shape in scene.shapes()
               if shape.interior_medium() is not None or shape.exterior_medium() is not None]
    holders += [name("sensor", sensor) for sensor in scene.sensors() if sensor.get_medium() is not None]
    if holders:
        raise ValueError(f"scene file {filename!r} has participating media ({', '.join(holders[:3])}"
                         f"{', ...' if len(holders) > 3 else ''}); sparselt's estimators and its path-traced baseline "
                         "and references trace surfaces only (as Mitsuba's path integrator): remove the media")
