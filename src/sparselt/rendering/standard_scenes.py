"""The standard benchmark scenes: seven small procedural scenes, one per difficulty rendering papers test.

Importing this module registers seven scenes with
:func:`sparselt.rendering.scenes.register`. Like
:mod:`sparselt.rendering.procedural`, it is pure Python: plain scene
dictionaries, Mitsuba shape primitives where they do (``sphere``,
``cylinder``, ``rectangle``, ``cube``, ``disk``), and three generated
meshes, some 12,000 triangles in all (the leaves of two crowns and the wire
sculpture of ``thin-geometry``, cached PLY files written by
:func:`sparselt.rendering.meshes.mesh_file`, their cache keys holding
:data:`MESH_REVISION`); it never imports Mitsuba.

``checker-dof``
    Fine checkerboard floor and backdrop with objects at three depths behind a
    thin-lens camera focused on the middle depth (depth of field).
``glossy-interior``
    A small closed room of rough metals and rough plastics under three
    ceiling area lights (glossy interreflection).
``soft-shadows``
    Objects on a floor under one large, close area light (wide penumbrae).
``thin-geometry``
    A wire fence, power lines, a wire sculpture and two foliage crowns,
    lit by the sun and the sky (sub-pixel geometry).
``mirror-room``
    A room with a wall mirror, chrome spheres and a glass sphere (specular
    chains).
``outdoor-texture``
    A long outdoor view over a finely checkered ground with striped and
    checkered objects, lit by the sun and the sky (texture under indirect
    light).
``glass-caustic``
    A glass sphere on a table under a small spherical light (a caustic that
    path tracing finds only by BSDF sampling).

:data:`SUITE_SETTINGS` gives, for each, the signal kind and the longest path
the benchmark suite renders it with, and why. Every scene renders at 128x128,
16 spp with Mitsuba's ``path`` integrator at that depth in well under a
second on two cores (LLVM).
"""

from __future__ import annotations

import numpy as np

from . import meshes
from .scenes import Camera, SceneSpec, Transform, register

#: Per scene: the signal kind (:data:`~sparselt.rendering.layout.KINDS`) and longest path (Mitsuba's
#: ``max_depth``) the standard suite renders it with, and why.
SUITE_SETTINGS = {
    "checker-dof": {
        "kind": "dof",
        "max_depth": 3,
        "reason": "Defocused spheres in front of and behind an in-focus fine checkerboard: the lens axes carry "
        "the blur, the image axes frequencies near the pixel rate.",
    },
    "glossy-interior": {
        "kind": "indirect",
        "max_depth": 3,
        "reason": "The secondary ray off a glossy floor and glossy objects carries sharp reflections of the "
        "lit room, a narrow lobe in the indirect axes.",
    },
    "soft-shadows": {
        "kind": "path",
        "max_depth": 3,
        "reason": "One large area light close to the objects: the light sample's axes decide the wide "
        "penumbrae at depth 2, the bounce off the floor fills them at depth 3.",
    },
    "thin-geometry": {
        "kind": "path",
        "max_depth": 3,
        "reason": "Wires and leaves narrower than a pixel against the sky: the image axes carry edges that "
        "no smooth reconstruction keeps.",
    },
    "mirror-room": {
        "kind": "path",
        "max_depth": 5,
        "reason": "A wall mirror, chrome and glass spheres: the room is seen through chains of up to three "
        "specular vertices before its first diffuse one.",
    },
    "outdoor-texture": {
        "kind": "indirect",
        "max_depth": 3,
        "reason": "Sun and sky over finely textured ground and objects: the bounced light is smooth but "
        "multiplied by texture at the pixel rate.",
    },
    "glass-caustic": {
        "kind": "path",
        "max_depth": 5,
        "reason": "The caustic of a glass sphere under a small light is a light-glass-glass-table-camera "
        "path (depth 4) that path tracing finds only by BSDF sampling.",
    },
}

#: Bumped whenever a mesh generator of this module changes its output (part of every mesh cache key).
MESH_REVISION = 1


# ---------------------------------------------------------------------------
# Helpers: colours, materials, textures, room shells
# ---------------------------------------------------------------------------


def _rgb(value):
    if isinstance(value, (int, float)):
        value = (value, value, value)
    return {"type": "rgb", "value": [float(v) for v in value]}


def _diffuse(reflectance):
    """A diffuse BSDF; ``reflectance`` is a colour or a texture dictionary."""
    return {"type": "diffuse", "reflectance": reflectance if isinstance(reflectance, dict) else _rgb(reflectance)}


def _rough_plastic(reflectance, alpha):
    reflectance = reflectance if isinstance(reflectance, dict) else _rgb(reflectance)
    return {"type": "roughplastic", "distribution": "ggx", "alpha": float(alpha), "diffuse_reflectance": reflectance}


def _rough_metal(material, alpha):
    return {"type": "roughconductor", "distribution": "ggx", "alpha": float(alpha), "material": material}


def _two_sided(bsdf):
    return {"type": "twosided", "bsdf": bsdf}


def _checkerboard(color0, color1, repeats_u, repeats_v=None):
    """Mitsuba's ``checkerboard`` texture with ``2 repeats`` checks along each uv axis.

    A uv axis with ``repeats`` below 1/2 stays in one half of one period, so
    ``_checkerboard(a, b, 20, 0.4)`` is a texture of 40 stripes across u.
    """
    repeats_v = repeats_u if repeats_v is None else repeats_v
    return {
        "type": "checkerboard",
        "color0": _rgb(color0),
        "color1": _rgb(color1),
        "to_uv": Transform().scale((float(repeats_u), float(repeats_v), 1.0)),
    }


def _rectangle(transform, bsdf):
    return {"type": "rectangle", "to_world": transform, "bsdf": bsdf}


def _floor(half_size, bsdf):
    """A square in the plane ``y = 0``, ``2 half_size`` wide, facing up."""
    return _rectangle(Transform().rotate((1.0, 0.0, 0.0), -90.0).scale(half_size), bsdf)


def _box(center, half_size, bsdf, angle=0.0):
    """A ``cube`` centred at ``center`` with half edge lengths ``half_size``, turned by ``angle`` degrees about y."""
    return {
        "type": "cube",
        "to_world": Transform().translate(center).rotate((0.0, 1.0, 0.0), angle).scale(half_size),
        "bsdf": bsdf,
    }


def _sphere(center, radius, bsdf):
    return {"type": "sphere", "center": [float(v) for v in center], "radius": float(radius), "bsdf": bsdf}


def _cylinder(start, end, radius, bsdf):
    return {"type": "cylinder", "p0": [float(v) for v in start], "p1": [float(v) for v in end], "radius": float(radius),
            "bsdf": bsdf}  # fmt: skip


def _ceiling_light(center, half_size, radiance):
    """A rectangle area light facing down (``-y``) at ``center``; ``half_size`` = (along x, along z)."""
    return {
        "type": "rectangle",
        "to_world": Transform().translate(center).rotate((1.0, 0.0, 0.0), 90.0).scale((half_size[0], half_size[1], 1.0)),
        "bsdf": _diffuse(0.0),
        "emitter": {"type": "area", "radiance": _rgb(radiance)},
    }


def _room(half_width, half_depth, height, bsdfs, overlap=0.2):
    """Floor, ceiling and four walls of a closed box room, all facing in.

    ``|x| <= half_width``, ``|z| <= half_depth``, ``0 <= y <= height``.
    Every rectangle reaches ``overlap`` beyond the room's edges into its
    neighbours, so that no light leaks through the seams.

    Parameters
    ----------
    bsdfs : dict
        BSDF of each of ``floor``, ``ceiling``, ``north`` (``z = -half_depth``),
        ``south``, ``west`` (``x = -half_width``) and ``east``.

    Returns
    -------
    dict
        Object name (``floor``, ``ceiling``, ``north-wall``, ...) -> shape.
    """
    rotate_x, rotate_y = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)
    wide, deep, tall = half_width + overlap, half_depth + overlap, 0.5 * height + overlap
    middle = 0.5 * height
    transforms = {
        "floor": Transform().rotate(rotate_x, -90.0).scale((wide, deep, 1.0)),
        "ceiling": Transform().translate((0.0, height, 0.0)).rotate(rotate_x, 90.0).scale((wide, deep, 1.0)),
        "north": Transform().translate((0.0, middle, -half_depth)).scale((wide, tall, 1.0)),
        "south": Transform().translate((0.0, middle, half_depth)).rotate(rotate_y, 180.0).scale((wide, tall, 1.0)),
        "west": Transform().translate((-half_width, middle, 0.0)).rotate(rotate_y, 90.0).scale((deep, tall, 1.0)),
        "east": Transform().translate((half_width, middle, 0.0)).rotate(rotate_y, -90.0).scale((deep, tall, 1.0)),
    }
    return {(side if side in ("floor", "ceiling") else f"{side}-wall"): _rectangle(transform, bsdfs[side])
            for side, transform in transforms.items()}


def _view_distance(origin, target, point):
    """Distance of ``point`` from a camera at ``origin`` looking at ``target``, along the view axis."""
    origin = np.asarray(origin, dtype=np.float64)
    axis = np.asarray(target, dtype=np.float64) - origin
    axis /= np.linalg.norm(axis)
    return float(np.dot(np.asarray(point, dtype=np.float64) - origin, axis))


def _camera(origin, target, fov, **lens):
    return Camera(to_world=Transform().look_at(origin, target, (0.0, 1.0, 0.0)), fov=float(fov), fov_axis="x",
                  near_clip=0.01, far_clip=1000.0, **lens)  # fmt: skip


# ---------------------------------------------------------------------------
# checker-dof
# ---------------------------------------------------------------------------

#: Camera of ``checker-dof``: position and the point it looks at.
CHECKER_DOF_CAMERA_ORIGIN = (0.0, 2.3, 6.5)
CHECKER_DOF_CAMERA_TARGET = (0.0, 0.45, 0.0)
#: Aperture radius of ``checker-dof``'s thin lens (metres).
CHECKER_DOF_APERTURE = 0.2
#: The objects of ``checker-dof``: (name, depth group, centre, radius); the camera focuses on the middle group.
CHECKER_DOF_SPHERES = (
    ("near-left", "near", (-0.6, 0.3, 3.3), 0.3),
    ("near-right", "near", (0.8, 0.22, 3.0), 0.22),
    ("middle", "middle", (-0.35, 0.5, 0.0), 0.5),
    ("far-left", "far", (-1.9, 0.8, -4.5), 0.8),
    ("far-right", "far", (1.6, 0.7, -4.0), 0.7),
)
#: Centre and half size of the checkered cube standing in focus beside the middle sphere.
CHECKER_DOF_CUBE = ((0.75, 0.35, 0.25), 0.35)


def checker_dof_focus_distance():
    """Distance along the view axis from the camera of ``checker-dof`` to the centre of its middle sphere."""
    centre = next(entry[2] for entry in CHECKER_DOF_SPHERES if entry[1] == "middle")
    return _view_distance(CHECKER_DOF_CAMERA_ORIGIN, CHECKER_DOF_CAMERA_TARGET, centre)


@register("checker-dof")
def checker_dof():
    """In-focus fine texture between defocused objects in front of and behind the focal plane.

    A floor and a backdrop wall with a fine checkerboard (20 cm checks on the
    floor, five pixels wide at the focal plane at 128x128 and foreshortened
    to one or two pixels deep; 25 cm on the backdrop), two spheres near the
    camera, a sphere and a checkered cube at the focal plane and two large
    spheres far behind it (:data:`CHECKER_DOF_SPHERES`), a rectangle area
    light above and a dim constant sky. The thin-lens camera (aperture
    radius :data:`CHECKER_DOF_APERTURE`) focuses on the middle sphere
    (:func:`checker_dof_focus_distance`): at 128x128 the circle of confusion
    is 7-9 pixels wide at the near spheres, 4 at the far ones and 5 at the
    backdrop, and the floor runs from blurred through sharp to blurred
    again.

    Notes
    -----
    Why it is in the suite: a defocused object in front of in-focus texture
    is the case where depth-of-field filters that blur along the image axes
    fail. The image-plane spectrum at a pixel mixes the in-focus texture's
    high frequencies with the blurred object's low ones, and a reconstruction
    must keep the first while averaging the lens axes for the second (the
    double wedge of Soler et al. 2009; the sheared and axis-aligned filters of
    Mehta et al. 2014 separate them). Kinds: ``dof`` (its purpose: axes
    ``x, y, lens_u, lens_v``), ``path``, ``indirect`` and ``path-indirect``.
    The effect shows from depth 2 (direct light); depth 3 adds the floor's
    bounce light and is the suite's setting (:data:`SUITE_SETTINGS`); deeper
    paths change nothing visible.

    References
    ----------
    Soler, C., Subr, K., Durand, F., Holzschuch, N., Sillion, F. (2009).
    Fourier depth of field. ACM Transactions on Graphics 28(2).
    Mehta, S. U., Yao, J., Ramamoorthi, R., Durand, F. (2014). Factored
    axis-aligned filtering for rendering multiple distribution effects. ACM
    Transactions on Graphics 33(4) (SIGGRAPH).
    """
    objects = {"type": "scene"}
    floor_checks = _checkerboard((0.70, 0.68, 0.62), (0.08, 0.08, 0.09), 50.0)  # 20 cm checks
    objects["floor"] = _floor(10.0, _diffuse(floor_checks))
    backdrop_checks = _checkerboard((0.62, 0.64, 0.70), (0.10, 0.12, 0.18), 32.0, 9.6)  # 25 cm checks
    objects["backdrop"] = _rectangle(Transform().translate((0.0, 2.4, -7.0)).scale((8.0, 2.4, 1.0)), _diffuse(backdrop_checks))
    colours = {"near-left": (0.75, 0.12, 0.08), "near-right": (0.9, 0.6, 0.1), "middle": (0.15, 0.35, 0.75),
               "far-left": (0.2, 0.55, 0.2), "far-right": (0.6, 0.2, 0.6)}  # fmt: skip
    for name, _, centre, radius in CHECKER_DOF_SPHERES:
        objects[f"sphere-{name}"] = _sphere(centre, radius, _rough_plastic(colours[name], 0.2))
    centre, half = CHECKER_DOF_CUBE
    objects["cube"] = _box(centre, half, _diffuse(_checkerboard((0.85, 0.85, 0.80), (0.10, 0.10, 0.10), 3.0)), angle=-25.0)
    objects["light"] = {
        "type": "rectangle",
        "to_world": Transform().look_at((-2.5, 5.0, 3.0), (0.0, 0.0, -0.5), (0.0, 1.0, 0.0)).scale(1.5),
        "bsdf": _diffuse(0.0),
        "emitter": {"type": "area", "radiance": _rgb((9.0, 8.6, 7.8))},
    }
    objects["sky"] = {"type": "constant", "radiance": _rgb((0.16, 0.18, 0.22))}
    camera = _camera(CHECKER_DOF_CAMERA_ORIGIN, CHECKER_DOF_CAMERA_TARGET, 40.0,
                     aperture_radius=CHECKER_DOF_APERTURE, focus_distance=checker_dof_focus_distance())  # fmt: skip
    return SceneSpec(
        name="checker-dof",
        description="Fine checkerboard floor and backdrop, spheres at three depths, thin lens focused on the "
        "middle sphere (defocus in front of and behind in-focus texture)",
        objects=objects,
        camera=camera,
        default_resolution=(128, 128),
    )


# ---------------------------------------------------------------------------
# glossy-interior
# ---------------------------------------------------------------------------

GLOSSY_ROOM_HALF_WIDTH = 2.0
GLOSSY_ROOM_HALF_DEPTH = 2.5
GLOSSY_ROOM_HEIGHT = 2.6


@register("glossy-interior")
def glossy_interior():
    """A closed room of rough metals and rough plastics under three ceiling area lights.

    The floor is a dark varnished rough plastic (GGX, alpha 0.08, index 1.9:
    about 10% specular reflection at normal incidence, more at grazing
    angles; blurred reflections of everything in the room), the west wall a
    blue rough plastic, the north wall carries a rough aluminium panel, and
    the room holds a rough aluminium sphere, a rough copper cylinder on a
    plinth, a rough gold sphere and a red rough plastic box. Three
    rectangle area lights (0.8 m by 1.6 m) hang just below the plaster
    ceiling. The room is closed (walls overlap at the seams): no light leaks
    in or out.

    Notes
    -----
    Why it is in the suite: glossy interreflection under area lights is the
    classic case for multiple importance sampling (Veach and Guibas 1995)
    and the bulk of the interior scenes of Bitterli's rendering resources
    (2016) that denoisers and path guiding are judged on. The secondary ray
    leaving a glossy vertex sees a sharp, shifted image of the room, so the
    indirect signal is concentrated in a narrow lobe of the ``bsdf1`` axes
    whose position moves with the pixel. Kinds: ``indirect`` (its purpose:
    axes ``x, y, bsdf1_u, bsdf1_v``), ``path``, ``path-indirect``, and
    ``dof`` with an aperture override. The glossy reflections of directly lit
    surfaces appear at depth 3 (the suite's setting, :data:`SUITE_SETTINGS`);
    depth 4 adds reflections of reflections (the metal spheres as the floor
    mirrors them) and the light bounced off the floor onto the ceiling seen
    in the metals; beyond that little changes. Light that reaches a diffuse
    surface by a glossy reflection (the ceiling lit through the floor) is
    found mostly by next-event estimation at the glossy vertex: the few
    samples in its lobe are the scene's fireflies.

    References
    ----------
    Veach, E., Guibas, L. J. (1995). Optimally combining sampling techniques
    for Monte Carlo rendering. SIGGRAPH '95.
    Bitterli, B. (2016). Rendering resources.
    https://benedikt-bitterli.me/resources/
    """
    half_width, half_depth, height = GLOSSY_ROOM_HALF_WIDTH, GLOSSY_ROOM_HALF_DEPTH, GLOSSY_ROOM_HEIGHT
    plaster = _diffuse((0.70, 0.68, 0.64))
    objects = {"type": "scene"}
    objects.update(_room(half_width, half_depth, height, {
        "floor": dict(_rough_plastic((0.20, 0.12, 0.06), 0.08), int_ior=1.9),  # a varnish reflecting 10%
        "ceiling": _diffuse((0.78, 0.78, 0.76)),
        "north": plaster, "south": plaster,
        "west": _rough_plastic((0.35, 0.45, 0.55), 0.15),
        "east": plaster,
    }))  # fmt: skip
    objects["panel"] = _rectangle(Transform().translate((0.3, 1.3, -half_depth + 0.02)).scale((1.1, 0.7, 1.0)),
                                  _rough_metal("Al", 0.25))  # fmt: skip
    objects["aluminium-sphere"] = _sphere((-0.9, 0.45, -0.9), 0.45, _rough_metal("Al", 0.15))
    objects["gold-sphere"] = _sphere((0.55, 0.3, 0.3), 0.3, _rough_metal("Au", 0.2))
    objects["plinth"] = _box((1.1, 0.3, -1.2), (0.3, 0.3, 0.3), _rough_plastic((0.75, 0.74, 0.70), 0.3))
    objects["copper-cylinder"] = _cylinder((1.1, 0.6, -1.2), (1.1, 1.3, -1.2), 0.2, _rough_metal("Cu", 0.15))
    objects["copper-cylinder-top"] = {
        "type": "disk",
        "to_world": Transform().translate((1.1, 1.3, -1.2)).rotate((1.0, 0.0, 0.0), -90.0).scale(0.2),
        "bsdf": _rough_metal("Cu", 0.15),
    }
    objects["red-box"] = _box((-1.2, 0.25, 0.6), (0.25, 0.25, 0.35), _rough_plastic((0.6, 0.06, 0.05), 0.1), angle=30.0)
    for index, x in enumerate((-1.05, 0.0, 1.05)):
        objects[f"light-{index}"] = _ceiling_light((x, height - 0.01, -0.6), (0.4, 0.8), (4.0, 3.8, 3.4))
    camera = _camera((1.5, 1.55, 2.3), (-0.3, 0.55, -1.0), 70.0)
    return SceneSpec(
        name="glossy-interior",
        description="Closed room of rough metals and rough plastics (glossy floor, metal spheres, copper "
        "cylinder, aluminium panel) under three ceiling area lights",
        objects=objects,
        camera=camera,
        default_resolution=(128, 128),
    )


# ---------------------------------------------------------------------------
# soft-shadows
# ---------------------------------------------------------------------------

#: Centre of ``soft-shadows``' area light (facing down, a little behind the objects) and its half size along
#: x and z (metres).
SOFT_SHADOW_LIGHT_CENTER = (0.0, 1.9, -0.9)
SOFT_SHADOW_LIGHT_HALF_SIZE = (1.0, 0.6)


@register("soft-shadows")
def soft_shadows():
    """Objects on a floor under one large area light close above them: wide penumbrae.

    A 2.0 m by 1.2 m area light faces down 1.9 m above a diffuse floor, a
    little behind a sphere, a box and a square pillar 1.3 m tall, so that the
    light's extent is comparable to its distance from the objects and the
    shadows fall towards the camera: the pillar's shadow is all penumbra, the
    sphere's and the box's have small umbrae inside wide penumbrae. A wall
    behind closes the view. No other light.

    Notes
    -----
    Why it is in the suite: the soft shadow of an area light is the first
    distribution effect of filtering methods (Egan et al. 2011; Mehta et al.
    2012): the visibility of the light sample is a step function in the
    light axes whose position moves with the pixel, so the light axes carry
    a sheared spectrum whose width is set by the light's size and the
    occluder's distance. Kinds: ``path`` (its purpose: the light sample is
    a pair of axes), ``path-indirect``, ``indirect``, and ``dof`` with an
    aperture override. Depth 2 (direct light) shows the penumbrae; depth 3
    (the suite's setting, :data:`SUITE_SETTINGS`) adds the bounce off the
    floor and wall that lightens the umbrae; deeper paths add little.

    References
    ----------
    Egan, K., Hecht, F., Durand, F., Ramamoorthi, R. (2011). Practical
    filtering for efficient ray-traced directional occlusion. ACM
    Transactions on Graphics 30(6) (SIGGRAPH Asia).
    Mehta, S. U., Wang, B., Ramamoorthi, R. (2012). Axis-aligned filtering
    for interactive sampled soft shadows. ACM Transactions on Graphics 31(6)
    (SIGGRAPH Asia).
    """
    objects = {"type": "scene"}
    objects["floor"] = _floor(6.0, _diffuse((0.62, 0.60, 0.56)))
    objects["back-wall"] = _rectangle(Transform().translate((0.0, 3.0, -2.2)).scale((6.0, 3.0, 1.0)),
                                      _diffuse((0.55, 0.58, 0.62)))  # fmt: skip
    objects["sphere"] = _sphere((-1.1, 0.42, 0.2), 0.42, _diffuse((0.70, 0.22, 0.15)))
    objects["box"] = _box((1.05, 0.3, 0.3), (0.3, 0.3, 0.3), _diffuse((0.25, 0.45, 0.70)), angle=35.0)
    objects["pillar"] = _box((0.05, 0.65, 0.0), (0.12, 0.65, 0.12), _diffuse((0.80, 0.78, 0.72)), angle=20.0)
    objects["light"] = _ceiling_light(SOFT_SHADOW_LIGHT_CENTER, SOFT_SHADOW_LIGHT_HALF_SIZE, (8.0, 7.6, 7.0))
    camera = _camera((0.0, 1.7, 4.6), (0.0, 0.35, 0.0), 50.0)
    return SceneSpec(
        name="soft-shadows",
        description="Sphere, box and pillar on a floor under one large, close area light (wide penumbrae)",
        objects=objects,
        camera=camera,
        default_resolution=(128, 128),
    )


# ---------------------------------------------------------------------------
# thin-geometry
# ---------------------------------------------------------------------------

#: Radius of the fence wires and of the power lines of ``thin-geometry`` (metres); a pixel is about 3.5 cm
#: wide at the fence at 128x128.
FENCE_WIRE_RADIUS = 0.005
POWER_LINE_RADIUS = 0.012


def _leaves(count, center, radii, leaf_size, seed, revision):
    """``count`` small flat leaves (two triangles each) scattered through an ellipsoid.

    Parameters
    ----------
    count : int
        Number of leaves.
    center, radii : sequence of 3 floats
        The crown: an ellipsoid; leaves are denser towards its surface.
    leaf_size : sequence of 2 floats
        Length and width of a leaf.
    seed : int
        Seed of the leaves' positions and orientations.
    revision : int
        :data:`MESH_REVISION` (part of the cache key only).

    Returns
    -------
    meshes.TriangleMesh
        ``2 count`` triangles; each leaf is a rhombus with its own four vertices.
    """
    rng = np.random.default_rng(seed)
    directions = rng.normal(size=(count, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    radius = rng.uniform(0.0, 1.0, size=(count, 1)) ** 0.25  # denser towards the crown's surface
    centres = np.asarray(center, dtype=np.float64) + directions * radius * np.asarray(radii, dtype=np.float64)
    # A random frame per leaf: its length along ``along``, its width along ``across``.
    along = rng.normal(size=(count, 3))
    along /= np.linalg.norm(along, axis=1, keepdims=True)
    across = np.cross(along, rng.normal(size=(count, 3)))
    across /= np.linalg.norm(across, axis=1, keepdims=True)
    length, width = leaf_size
    scale = rng.uniform(0.7, 1.3, size=(count, 1))
    tips = 0.5 * length * scale * along
    sides = 0.5 * width * scale * across
    corners = np.stack([centres - tips, centres - sides, centres + tips, centres + sides], axis=1)
    base = 4 * np.arange(count)[:, None]
    faces = np.concatenate([base + np.array([0, 1, 2]), base + np.array([0, 2, 3])])
    return meshes.TriangleMesh(corners.reshape(-1, 3), faces)


def _wire_sculpture(revision):
    """A thin wire (7 mm tube) along a (3, 7) torus knot, 0.6 m across; ``revision``: part of the cache key."""
    return meshes.torus_knot(p=3, q=7, knot_radius=0.3, tube_radius=0.007, segments=400, sides=4)


def _sagging_wire(start, end, sag, pieces):
    """Points of a wire hanging between ``start`` and ``end`` (a parabola ``sag`` below the chord at the middle)."""
    start, end = np.asarray(start, dtype=np.float64), np.asarray(end, dtype=np.float64)
    t = np.linspace(0.0, 1.0, pieces + 1)[:, None]
    points = start + t * (end - start)
    points[:, 1] -= 4.0 * sag * (t[:, 0] * (1.0 - t[:, 0]))
    return points


@register("thin-geometry")
def thin_geometry():
    """Wires and leaves narrower than a pixel, lit by the sun and the sky.

    A wire fence (thin posts and four horizontal wires of radius
    :data:`FENCE_WIRE_RADIUS`, about a quarter of a pixel wide at 128x128), three
    sagging power lines between two poles against the sky, a wire sculpture
    (a 7 mm tube along a torus knot) on a plinth, a tree and a bush whose
    crowns are 4500 small flat leaves (generated PLY meshes, two-sided),
    all on a grass-coloured ground under a directional sun and a constant
    sky. Pinhole camera.

    Notes
    -----
    Why it is in the suite: geometry thinner than a pixel makes the image
    signal discontinuous at the pixel scale and partly covered inside a
    pixel, so feature-guided filters (whose normals and albedo change from
    sample to sample there) and sparse reconstructions of the image axes
    both lose it; foliage is the standard failure case of the denoisers
    surveyed by Zwicker et al. (2015). The sun makes hard, thin shadows of
    the wires on the ground too. Kinds: ``path`` (its purpose), ``indirect``,
    ``path-indirect``, and ``dof`` with an aperture override (``--aperture
    0.05`` alone focuses on the fence: the central ray sees the sky, so the
    camera's own focus distance, the fence's, is kept). Depth 2 shows the
    geometry and its sunlight; depth 3 (the suite's setting,
    :data:`SUITE_SETTINGS`) adds light bounced inside the crowns and off
    the ground.

    References
    ----------
    Zwicker, M., Jarosz, W., Lehtinen, J., Moon, B., Ramamoorthi, R.,
    Rousselle, F., Sen, P., Soler, C., Yoon, S.-E. (2015). Recent advances
    in adaptive sampling and reconstruction for Monte Carlo rendering.
    Computer Graphics Forum 34(2) (Eurographics STAR).
    """
    objects = {"type": "scene"}
    objects["ground"] = _floor(60.0, _diffuse((0.22, 0.28, 0.12)))
    wood = _diffuse((0.35, 0.25, 0.15))
    steel = _rough_metal("Cr", 0.3)
    # The fence: posts every 0.6 m along x at z = 0.8, four wires.
    posts = np.arange(-3.0, 3.01, 0.6)
    for index, x in enumerate(posts):
        objects[f"fence-post-{index}"] = _cylinder((x, 0.0, 0.8), (x, 1.25, 0.8), 0.025, wood)
    for index, y in enumerate((0.3, 0.6, 0.9, 1.2)):
        objects[f"fence-wire-{index}"] = _cylinder((posts[0], y, 0.8 + 0.03), (posts[-1], y, 0.8 + 0.03),
                                                   FENCE_WIRE_RADIUS, steel)  # fmt: skip
    # Power lines: two poles, three sagging wires in straight pieces.
    poles = ((-7.0, -9.0), (6.0, -11.0))
    for index, (x, z) in enumerate(poles):
        objects[f"pole-{index}"] = _cylinder((x, 0.0, z), (x, 6.4, z), 0.09, wood)
        objects[f"cross-arm-{index}"] = _box((x, 6.2, z), (0.9, 0.05, 0.05), wood)
    for line, offset in enumerate((-0.75, 0.0, 0.75)):
        start = (poles[0][0] + offset, 6.25, poles[0][1])
        end = (poles[1][0] + offset, 6.25, poles[1][1])
        points = _sagging_wire(start, end, 0.9, 6)
        for piece in range(len(points) - 1):
            objects[f"power-line-{line}-{piece}"] = _cylinder(points[piece], points[piece + 1], POWER_LINE_RADIUS,
                                                              _diffuse(0.05))  # fmt: skip
    # The wire sculpture on a plinth.
    objects["plinth"] = _box((1.6, 0.35, -0.8), (0.2, 0.35, 0.2), _diffuse((0.7, 0.68, 0.64)))
    sculpture = meshes.mesh_file("thin-geometry-wire-sculpture", _wire_sculpture, revision=MESH_REVISION)
    objects["wire-sculpture"] = {"type": "ply", "filename": sculpture, "bsdf": _rough_metal("Cu", 0.25),
                                 "to_world": Transform().translate((1.6, 1.05, -0.8)).rotate((1.0, 0.0, 0.0), 70.0)}
    # A tree and a bush.
    objects["trunk"] = _cylinder((-1.8, 0.0, -2.2), (-1.8, 2.2, -2.2), 0.1, wood)
    leaf = _two_sided(_diffuse((0.12, 0.32, 0.06)))
    crown = meshes.mesh_file("thin-geometry-crown", _leaves, count=3000, center=(-1.8, 2.6, -2.2), radii=(1.1, 0.9, 1.1),
                             leaf_size=(0.12, 0.06), seed=11, revision=MESH_REVISION)  # fmt: skip
    objects["crown"] = {"type": "ply", "filename": crown, "bsdf": leaf}
    bush = meshes.mesh_file("thin-geometry-bush", _leaves, count=1500, center=(2.4, 0.45, 0.0), radii=(0.7, 0.45, 0.55),
                            leaf_size=(0.09, 0.05), seed=12, revision=MESH_REVISION)  # fmt: skip
    objects["bush"] = {"type": "ply", "filename": bush, "bsdf": _two_sided(_diffuse((0.16, 0.30, 0.08)))}
    objects["sun"] = {"type": "directional", "direction": [0.45, -0.6, -0.65], "irradiance": _rgb((3.2, 3.0, 2.6))}
    objects["sky"] = {"type": "constant", "radiance": _rgb((0.40, 0.50, 0.70))}
    origin, target = (0.3, 1.35, 5.2), (0.0, 1.5, -2.0)
    # A pinhole; its focus distance (the fence's) is the one a thin lens given by --aperture alone keeps, the
    # central ray passing over the fence into the sky.
    camera = _camera(origin, target, 55.0, focus_distance=_view_distance(origin, target, (0.0, 1.2, 0.8)))
    return SceneSpec(
        name="thin-geometry",
        description="Wire fence, sagging power lines, a wire sculpture and leafy crowns (sub-pixel geometry) "
        "under a directional sun and a constant sky",
        objects=objects,
        camera=camera,
        default_resolution=(128, 128),
    )


# ---------------------------------------------------------------------------
# mirror-room
# ---------------------------------------------------------------------------

MIRROR_ROOM_HALF_WIDTH = 2.0
MIRROR_ROOM_HALF_DEPTH = 2.5
MIRROR_ROOM_HEIGHT = 2.6


@register("mirror-room")
def mirror_room():
    """A room with a wall mirror, chrome spheres and a glass sphere; diffuse walls, one area light.

    A flat silver mirror (a smooth ``conductor``) covers most of the west
    wall; two chrome spheres and a glass sphere (smooth ``dielectric``, BK7)
    stand on a checkered floor, the glass one on a low plinth. The walls are
    diffuse and differently coloured so that their reflections can be told
    apart; a rectangle area light under the ceiling lights the room, which
    is closed.

    Notes
    -----
    Why it is in the suite: perfectly specular surfaces make paths whose
    vertices before the first diffuse one are fixed by the camera ray (``E
    S* D ...``, Heckbert's notation): the image through the mirror and the
    spheres is sharp, discontinuous at their silhouettes and depends on no
    BSDF axis there, while the light reaching the floor through the glass is
    a caustic (Veach 1997, ch. 8). Specular chains also defeat the shifts of
    gradient-domain methods and the features of feature-guided filters.
    Kinds: ``path`` (its purpose), ``path-indirect``, ``indirect``, and
    ``dof`` with an aperture override. Depth 3 shows the directly lit room in
    the mirror; depth 4 through the glass sphere and in the chrome spheres
    seen in the mirror; depth 5 (the suite's setting, :data:`SUITE_SETTINGS`)
    the glass sphere in the mirror and the glass sphere's caustic seen in the
    mirror. The light's image in the mirror and in the spheres lights the
    room too, by caustic paths that path tracing finds only by BSDF sampling
    (from depth 3 on): the scene's fireflies.

    References
    ----------
    Heckbert, P. S. (1990). Adaptive radiosity textures for bidirectional ray
    tracing. SIGGRAPH '90.
    Veach, E. (1997). Robust Monte Carlo Methods for Light Transport
    Simulation. PhD thesis, Stanford University.
    """
    half_width, half_depth, height = MIRROR_ROOM_HALF_WIDTH, MIRROR_ROOM_HALF_DEPTH, MIRROR_ROOM_HEIGHT
    objects = {"type": "scene"}
    objects.update(_room(half_width, half_depth, height, {
        "floor": _diffuse(_checkerboard((0.62, 0.60, 0.56), (0.25, 0.24, 0.22), 4.0)),
        "ceiling": _diffuse((0.80, 0.80, 0.78)),
        "north": _diffuse((0.30, 0.45, 0.62)),
        "south": _diffuse((0.72, 0.55, 0.30)),
        "west": _diffuse((0.70, 0.70, 0.68)),
        "east": _diffuse((0.62, 0.25, 0.20)),
    }))  # fmt: skip
    # The mirror stands just in front of its dark frame (a thin box against the wall).
    objects["mirror-frame"] = _box((-half_width + 0.015, 1.25, -0.5), (0.015, 0.9, 1.65), _diffuse((0.15, 0.10, 0.07)))
    objects["mirror"] = _rectangle(
        Transform().translate((-half_width + 0.035, 1.25, -0.5)).rotate((0.0, 1.0, 0.0), 90.0).scale((1.55, 0.8, 1.0)),
        {"type": "conductor", "material": "Ag"},
    )
    # The camera looks at the mirror from the south-east; the mirror shows the north-east part of the room,
    # where the chrome spheres stand.
    chrome = {"type": "conductor", "material": "Cr"}
    objects["chrome-sphere-large"] = _sphere((0.7, 0.5, -1.5), 0.5, chrome)
    objects["chrome-sphere-small"] = _sphere((1.3, 0.28, -0.3), 0.28, chrome)
    objects["plinth"] = _box((-0.7, 0.15, 0.2), (0.3, 0.15, 0.3), _diffuse((0.75, 0.74, 0.70)))
    objects["glass-sphere"] = _sphere((-0.7, 0.68, 0.2), 0.38, {"type": "dielectric", "int_ior": "bk7", "ext_ior": "air"})
    objects["light"] = _ceiling_light((0.2, height - 0.01, -0.6), (0.8, 0.6), (6.0, 5.7, 5.2))
    camera = _camera((1.6, 1.5, 2.25), (-1.0, 0.8, -0.7), 70.0)
    return SceneSpec(
        name="mirror-room",
        description="Closed room with a wall mirror, two chrome spheres and a glass sphere, diffuse coloured "
        "walls and one area light (specular chains)",
        objects=objects,
        camera=camera,
        default_resolution=(128, 128),
    )


# ---------------------------------------------------------------------------
# outdoor-texture
# ---------------------------------------------------------------------------


@register("outdoor-texture")
def outdoor_texture():
    """A long outdoor view over finely textured ground and objects, lit by the sun and the sky.

    A ground plane 400 m wide with 0.5 m checks runs to the horizon; on it
    stand a row of checkered cubes and striped columns receding from the
    camera, striped spheres and a long wall with a fine brick-like
    checkerboard. A directional sun and a constant sky light everything; the
    sky is seen above the horizon. Pinhole camera.

    Notes
    -----
    Why it is in the suite: indirect light is smooth, but the radiance the
    camera sees is that light times the texture of the surface it lands on,
    so the image signal carries the texture's frequencies up to the pixel
    rate (and beyond it towards the horizon) whatever the light does. Filters
    of indirect light therefore filter the irradiance and multiply the
    texture back (Mehta et al. 2013), and a sparse reconstruction must spend
    its coefficients on the texture. Kinds: ``indirect`` (its purpose: the
    light bounced off the sunlit ground onto the shaded sides of the
    objects), ``path``, ``path-indirect``, and ``dof`` with an aperture
    override. Depth 3 (the suite's setting, :data:`SUITE_SETTINGS`) holds
    the one bounce that carries most of the indirect light outdoors.

    References
    ----------
    Mehta, S. U., Wang, B., Ramamoorthi, R., Durand, F. (2013). Axis-aligned
    filtering for interactive physically-based diffuse indirect lighting. ACM
    Transactions on Graphics 32(4) (SIGGRAPH).
    """
    objects = {"type": "scene"}
    objects["ground"] = _floor(200.0, _diffuse(_checkerboard((0.55, 0.50, 0.42), (0.20, 0.18, 0.15), 400.0)))
    for index in range(6):
        z = -2.0 - 5.0 * index
        objects[f"cube-{index}"] = _box((-2.2, 0.5, z), (0.5, 0.5, 0.5),
                                        _diffuse(_checkerboard((0.80, 0.78, 0.72), (0.15, 0.20, 0.45), 4.0)),
                                        angle=15.0 * index)  # fmt: skip
        objects[f"column-{index}"] = _cylinder((2.4, 0.0, z), (2.4, 2.5, z), 0.22,
                                               _diffuse(_checkerboard((0.75, 0.70, 0.60), (0.45, 0.12, 0.08), 0.4, 10.0)))
        objects[f"column-{index}-top"] = {
            "type": "disk",
            "to_world": Transform().translate((2.4, 2.5, z)).rotate((1.0, 0.0, 0.0), -90.0).scale(0.22),
            "bsdf": _diffuse((0.75, 0.70, 0.60)),
        }
    stripes = _diffuse(_checkerboard((0.85, 0.80, 0.30), (0.10, 0.25, 0.15), 12.0, 0.4))
    objects["sphere-near"] = _sphere((0.4, 0.6, -1.0), 0.6, stripes)
    objects["sphere-far"] = _sphere((-0.5, 0.9, -12.0), 0.9, stripes)
    bricks = _diffuse(_checkerboard((0.62, 0.32, 0.20), (0.45, 0.22, 0.14), 60.0, 8.0))
    objects["wall"] = _box((0.0, 1.0, -32.0), (12.0, 1.0, 0.2), bricks)
    objects["sun"] = {"type": "directional", "direction": [-0.55, -0.5, -0.65], "irradiance": _rgb((3.4, 3.1, 2.7))}
    objects["sky"] = {"type": "constant", "radiance": _rgb((0.35, 0.45, 0.65))}
    camera = _camera((0.6, 1.6, 4.5), (0.0, -2.0, -20.0), 60.0)
    return SceneSpec(
        name="outdoor-texture",
        description="Long outdoor view over a finely checkered ground with checkered cubes, striped columns and "
        "spheres and a brick wall, under a directional sun and a constant sky",
        objects=objects,
        camera=camera,
        default_resolution=(128, 128),
    )


# ---------------------------------------------------------------------------
# glass-caustic
# ---------------------------------------------------------------------------

#: Height of ``glass-caustic``'s table top, and its glass sphere (centre, radius) resting on it.
TABLE_HEIGHT = 0.8
GLASS_SPHERE_RADIUS = 0.25
GLASS_SPHERE_CENTER = (0.0, TABLE_HEIGHT + GLASS_SPHERE_RADIUS, 0.0)
#: The small spherical light of ``glass-caustic`` (centre, radius).
CAUSTIC_LIGHT_CENTER = (-0.52, 1.94, -1.2)
CAUSTIC_LIGHT_RADIUS = 0.05


def caustic_center():
    """Where the glass sphere of ``glass-caustic`` focuses the light onto the table (paraxial optics).

    A ball lens of index ``n`` and radius ``r`` has both principal planes at
    its centre and the focal length ``f = n r / (2 (n - 1))`` (0.37 m for
    BK7 here); the light, at ``d`` = 1.6 m from the centre, is imaged
    ``1 / (1/f - 1/d)`` = 0.48 m beyond it, on the line from the light
    through the centre. That line meets the table 0.44 m from the centre,
    just short of the image, and 0.37 m (more than a radius) from the point
    where the sphere touches the table: the caustic is a small bright disc
    around the point returned, inside the sphere's shadow and in view.

    Returns
    -------
    numpy.ndarray
        ``(x, y, z)`` on the table top.
    """
    centre = np.asarray(GLASS_SPHERE_CENTER, dtype=np.float64)
    direction = centre - np.asarray(CAUSTIC_LIGHT_CENTER, dtype=np.float64)
    distance = (centre[1] - TABLE_HEIGHT) / -direction[1]
    return centre + distance * direction


@register("glass-caustic")
def glass_caustic():
    """A glass sphere on a table under a small spherical light: the caustic beneath it.

    A solid glass sphere (smooth ``dielectric``, BK7) rests on a diffuse
    wooden table in a room corner (floor and two walls); a small spherical
    area light (radius :data:`CAUSTIC_LIGHT_RADIUS`, 55 degrees from the
    zenith seen from the sphere, behind it and out of the camera's view)
    throws the sphere's shadow forwards across the table with the focused
    caustic in it (:func:`caustic_center`). A dim constant environment
    fills the rest.

    Notes
    -----
    Why it is in the suite: the caustic is carried by paths ``L S S D E``
    (light, glass in, glass out, table, camera). A path tracer connects the
    table to the light by next-event estimation, and that shadow ray is
    blocked by the glass; only BSDF sampling at the table, a diffuse
    direction that happens to pass through the sphere and leave it towards
    the light's small solid angle, finds them (Veach 1997, ch. 8 and 10). The
    caustic is bright, small and very noisy: the hardest local estimate in
    the suite, and the class that ``render_path_classes`` separates. Kinds:
    ``path`` (its purpose), ``path-indirect``, ``indirect`` (its secondary
    ray through the glass carries the caustic), and ``dof`` with an aperture
    override. The caustic needs depth 4 (camera-table, table-glass,
    glass-glass, glass-light); depth 5 (the suite's setting,
    :data:`SUITE_SETTINGS`) adds the paths with one internal reflection in
    the sphere and the caustic mirrored in the sphere's surface (seen
    through the sphere it needs depth 6).

    References
    ----------
    Heckbert, P. S. (1990). Adaptive radiosity textures for bidirectional ray
    tracing. SIGGRAPH '90.
    Jensen, H. W. (1996). Global illumination using photon maps. Eurographics
    Workshop on Rendering.
    Veach, E. (1997). Robust Monte Carlo Methods for Light Transport
    Simulation. PhD thesis, Stanford University.
    """
    objects = {"type": "scene"}
    objects["floor"] = _floor(4.0, _diffuse((0.45, 0.45, 0.45)))
    objects["back-wall"] = _rectangle(Transform().translate((0.0, 2.0, -1.5)).scale((4.0, 2.0, 1.0)), _diffuse((0.60, 0.62, 0.65)))
    objects["side-wall"] = _rectangle(Transform().translate((-2.0, 2.0, 0.0)).rotate((0.0, 1.0, 0.0), 90.0).scale((4.0, 2.0, 1.0)),
                                      _diffuse((0.65, 0.60, 0.55)))  # fmt: skip
    wood = _diffuse((0.55, 0.38, 0.22))
    top = 0.03
    objects["table-top"] = _box((0.0, TABLE_HEIGHT - top, 0.0), (1.0, top, 0.6), wood)
    for index, (x, z) in enumerate(((-0.9, -0.5), (0.9, -0.5), (-0.9, 0.5), (0.9, 0.5))):
        objects[f"table-leg-{index}"] = _box((x, 0.5 * (TABLE_HEIGHT - 2 * top), z), (0.04, 0.5 * (TABLE_HEIGHT - 2 * top), 0.04), wood)
    objects["glass-sphere"] = _sphere(GLASS_SPHERE_CENTER, GLASS_SPHERE_RADIUS,
                                      {"type": "dielectric", "int_ior": "bk7", "ext_ior": "air"})  # fmt: skip
    objects["light"] = {
        "type": "sphere",
        "center": list(CAUSTIC_LIGHT_CENTER),
        "radius": CAUSTIC_LIGHT_RADIUS,
        "emitter": {"type": "area", "radiance": _rgb((580.0, 545.0, 490.0))},
    }
    objects["fill"] = {"type": "constant", "radiance": _rgb((0.06, 0.065, 0.075))}
    camera = _camera((0.7, 2.1, 2.3), (0.05, TABLE_HEIGHT, 0.1), 42.0)
    return SceneSpec(
        name="glass-caustic",
        description="Glass sphere on a diffuse table under a small spherical light (a caustic found only by "
        "BSDF sampling), dim constant fill",
        objects=objects,
        camera=camera,
        default_resolution=(128, 128),
    )
