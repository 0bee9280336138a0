"""The standard benchmark scenes (`sparselt.rendering.standard_scenes`): registered, valid, and showing their effect.

Small films of the real scenes, fixed seeds. Bounds that come from renders are
conservative against the values measured when the tests were written (quoted
beside each).
"""

import inspect
from dataclasses import replace

import numpy as np
import pytest

from sparselt.cli import main
from sparselt.images import luminance
from sparselt.rendering import standard_scenes
from sparselt.rendering.layout import KINDS, path_layout
from sparselt.rendering.scenes import SCENES, Camera, SceneSpec, Transform, get_scene, scene_names
from sparselt.rendering.setup import SceneSetup
from sparselt.rendering.standard_scenes import SUITE_SETTINGS

NAMES = ("checker-dof", "glossy-interior", "soft-shadows", "thin-geometry", "mirror-room", "outdoor-texture",
         "glass-caustic")


def _values(value):
    if isinstance(value, dict):
        for item in value.values():
            yield from _values(item)
    elif isinstance(value, (list, tuple)):
        for item in value:
            yield from _values(item)
    else:
        yield value


def _without(spec, prefixes):
    """``spec`` with the objects whose names start with one of ``prefixes`` removed (the same camera)."""
    kept = {key: value for key, value in spec.objects.items() if not key.startswith(prefixes)}
    assert len(kept) < len(spec.objects)
    return replace(spec, name=f"{spec.name}-without", objects=kept)


def _load(spec_or_name, resolution, max_depth=3):
    if isinstance(spec_or_name, SceneSpec):
        return SceneSetup(spec_or_name.name, max_depth=max_depth, scene_spec=spec_or_name).load(resolution).scene
    return SceneSetup(spec_or_name, max_depth=max_depth).load(resolution).scene


def _pixel(camera, point, resolution):
    """(row, column) of the film pixel that a pinhole ``camera`` (look_at transform, fov along x) maps ``point`` to."""
    (_, origin, target, up), = camera.to_world.operations
    origin = np.asarray(origin)
    forward = np.asarray(target) - origin
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, up)
    right /= np.linalg.norm(right)
    upward = np.cross(right, forward)
    offset = np.asarray(point) - origin
    tangent = np.tan(np.radians(camera.fov / 2))
    u = offset @ right / (offset @ forward) / tangent
    v = offset @ upward / (offset @ forward) / tangent
    width, height = resolution
    return (1 - v * width / height) * height / 2, (1 + u) * width / 2


# ---------------------------------------------------------------------------
# Registry and specifications (no renderer)
# ---------------------------------------------------------------------------


def test_the_seven_scenes_are_registered_listed_and_in_the_suite_settings(capsys):
    assert tuple(SUITE_SETTINGS) == NAMES
    assert set(NAMES) <= set(scene_names()) and set(NAMES) <= set(SCENES)
    assert main(["scenes"]) == 0
    listed = capsys.readouterr().out
    for name in NAMES:
        assert name in listed


@pytest.mark.parametrize("name", NAMES)
def test_suite_settings_are_valid_for_the_scene(name):
    settings = SUITE_SETTINGS[name]
    assert set(settings) == {"kind", "max_depth", "reason"}
    assert settings["kind"] in KINDS
    assert isinstance(settings["max_depth"], int) and 2 <= settings["max_depth"] <= 6
    reason = settings["reason"]
    assert 40 < len(reason) < 250 and reason.endswith(".") and reason.count(". ") == 0  # one sentence
    # The setup validates (a dof kind needs the scene's own thin lens, no override).
    SceneSetup(name, kind=settings["kind"], max_depth=settings["max_depth"]).validate()


@pytest.mark.parametrize("name", NAMES)
def test_specification_is_a_plain_scene_dictionary_with_a_camera(name):
    spec = get_scene(name)
    assert spec.name == name and spec.filename is None and spec.objects["type"] == "scene"
    assert len(spec.description) > 40 and tuple(spec.default_resolution) == (128, 128)
    assert "sensor" not in spec.objects and "integrator" not in spec.objects
    for key, entry in spec.objects.items():
        if isinstance(entry, dict):
            assert entry.get("type") not in ("perspective", "thinlens"), key
            if "to_world" in entry:
                assert isinstance(entry["to_world"], Transform), key
    assert not any(isinstance(value, np.ndarray) for value in _values(spec.objects))
    assert isinstance(spec.camera, Camera) and isinstance(spec.camera.to_world, Transform)
    assert 20.0 <= spec.camera.fov <= 90.0
    emitters = [entry for entry in spec.objects.values() if isinstance(entry, dict)
                and ("emitter" in entry or entry.get("type") in ("constant", "directional"))]
    assert emitters
    # A thin lens exactly where the suite renders depth of field.
    assert spec.camera.thin_lens == (SUITE_SETTINGS[name]["kind"] == "dof")


@pytest.mark.parametrize("name", NAMES)
def test_docstring_says_why_which_kinds_and_which_depth(name):
    text = inspect.getdoc(SCENES[name])
    for section in ("Notes", "References", "Why it is in the suite"):
        assert section in text
    assert f"``{SUITE_SETTINGS[name]['kind']}``" in text
    assert f"depth {SUITE_SETTINGS[name]['max_depth']}" in " ".join(text.lower().split())


def test_meshes_stay_small():
    """The generated meshes: leaves and the wire sculpture, some 12k triangles in all."""
    triangles = 0
    for name in NAMES:
        for entry in get_scene(name).objects.values():
            if isinstance(entry, dict) and entry.get("type") == "ply":
                with open(entry["filename"], "rb") as handle:
                    header = handle.read(400).split(b"end_header")[0].decode("ascii")
                triangles += int(next(line.split()[2] for line in header.splitlines() if line.startswith("element face")))
    assert 5_000 < triangles < 15_000


def test_thin_geometry_wires_are_narrower_than_a_pixel():
    """At 128x128 every wire is at most half a pixel wide where it is (measured 0.29 px for the fence wires,
    0.19-0.20 px for the power lines), and there are many of them."""
    spec = get_scene("thin-geometry")
    camera = spec.camera
    (_, origin, target, _), = camera.to_world.operations
    axis = np.subtract(target, origin) / np.linalg.norm(np.subtract(target, origin))
    pixel_per_metre_of_depth = 2 * np.tan(np.radians(camera.fov / 2)) / 128
    wires = {key: entry for key, entry in spec.objects.items() if key.startswith(("fence-wire", "power-line"))}
    assert len(wires) >= 10
    for key, entry in wires.items():
        nearest = min(float(np.subtract(end, origin) @ axis) for end in (entry["p0"], entry["p1"]))
        assert 2 * entry["radius"] < 0.5 * nearest * pixel_per_metre_of_depth, key


def test_checker_dof_focuses_on_the_middle_depth_with_blur_in_front_and_behind():
    camera = get_scene("checker-dof").camera
    assert camera.thin_lens and camera.aperture_radius == standard_scenes.CHECKER_DOF_APERTURE
    origin, target = standard_scenes.CHECKER_DOF_CAMERA_ORIGIN, standard_scenes.CHECKER_DOF_CAMERA_TARGET
    axis = np.subtract(target, origin) / np.linalg.norm(np.subtract(target, origin))
    depths = {group: [float(np.subtract(centre, origin) @ axis) for _, g, centre, _ in standard_scenes.CHECKER_DOF_SPHERES
                      if g == group] for group in ("near", "middle", "far")}  # fmt: skip
    assert camera.focus_distance == pytest.approx(depths["middle"][0])
    # Circle of confusion in pixels at 128 wide: measured 7.4-9.0 in front, 3.8-4.0 behind.
    pixels_per_tangent = 128 / (2 * np.tan(np.radians(camera.fov / 2)))
    for group, least in (("near", 5.0), ("far", 2.5)):
        for depth in depths[group]:
            blur = 2 * camera.aperture_radius * abs(1 / depth - 1 / camera.focus_distance) * pixels_per_tangent
            assert blur > least, (group, depth, blur)


def test_glass_caustic_focuses_outside_the_sphere_on_the_table():
    centre = np.asarray(standard_scenes.GLASS_SPHERE_CENTER)
    caustic = standard_scenes.caustic_center()
    assert caustic[1] == pytest.approx(standard_scenes.TABLE_HEIGHT)
    horizontal = np.hypot(*(caustic - centre)[[0, 2]])
    assert standard_scenes.GLASS_SPHERE_RADIUS < horizontal < 2 * standard_scenes.GLASS_SPHERE_RADIUS
    light = get_scene("glass-caustic").objects["light"]
    distance = np.linalg.norm(np.asarray(light["center"]) - centre)
    assert light["type"] == "sphere" and light["emitter"]["type"] == "area"
    assert light["radius"] < 0.05 * distance  # small: a solid angle BSDF sampling rarely hits


# ---------------------------------------------------------------------------
# Renders
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("name", NAMES)
def test_renders_a_finite_sensible_image(name):
    """Mitsuba's path integrator, 32x32, 16 spp, at the suite's depth: mean luminance measured 0.16-0.41."""
    depth = SUITE_SETTINGS[name]["max_depth"]
    image, _ = _load(name, (32, 32), depth).render_path(16, depth, 1)
    assert image.shape == (32, 32, 3) and np.all(np.isfinite(image)) and image.min() >= 0
    brightness = luminance(image.astype(np.float64))
    assert 0.05 < brightness.mean() < 2.0
    assert np.mean(brightness < 1e-4) < 0.05  # no black regions (light leaks, framing)


@pytest.mark.parametrize("name", NAMES)
def test_the_suite_kind_renders(name):
    """The kind's own estimator at the suite's depth, 16x16, 4 spp: finite and not black."""
    kind, depth = SUITE_SETTINGS[name]["kind"], SUITE_SETTINGS[name]["max_depth"]
    spec = get_scene(name)
    axes = len(path_layout(kind, depth, thin_lens=spec.camera.thin_lens, hide_emitters=spec.hide_emitters).axes)
    loaded = SceneSetup(name, kind=kind, max_depth=depth, shape=(16, 16) + (2,) * (axes - 2)).validate().load()
    estimate, nonfinite = loaded.scene.render_estimator(loaded.layout, 4, 2)
    assert estimate.shape == (16, 16, 3) and np.all(np.isfinite(estimate)) and nonfinite == 0
    assert estimate.min() >= 0 and luminance(estimate.astype(np.float64)).mean() > 0.01


def test_checker_dof_blurs_in_front_of_and_behind_the_focal_plane_only():
    """Albedo through the lens against a pinhole, by pinhole depth: the mean absolute difference is measured
    0.085 in front (nearer than 4.5), 0.070 behind (beyond 10) and 0.017 at the focal plane."""
    spec = get_scene("checker-dof")
    pinhole = replace(spec, name="checker-dof-pinhole", camera=replace(spec.camera, aperture_radius=None))
    lens_buffers, _ = _load(spec, (48, 48)).render_aovs(64, 1)
    pinhole_buffers, _ = _load(pinhole, (48, 48)).render_aovs(64, 1)
    depth = pinhole_buffers["depth"]
    difference = np.abs(luminance(lens_buffers["albedo"].astype(np.float64))
                        - luminance(pinhole_buffers["albedo"].astype(np.float64)))
    focus = spec.camera.focus_distance
    near, focal, far = depth < 4.5, np.abs(depth - focus) < 0.8, depth > 10.0
    assert min(near.sum(), focal.sum(), far.sum()) > 100  # each depth holds a good part of the film
    assert difference[near].mean() > 2.5 * difference[focal].mean()
    assert difference[far].mean() > 2.5 * difference[focal].mean()


def _thin_lines(image, contrast):
    """Pixels brighter or darker than both neighbours along x or along y by more than ``contrast``: lines one pixel thin."""
    centre = image[1:-1, 1:-1]

    def extremum(first, second):
        return (((centre - first > contrast) & (centre - second > contrast))
                | ((first - centre > contrast) & (second - centre > contrast)))

    return extremum(image[1:-1, :-2], image[1:-1, 2:]) | extremum(image[:-2, 1:-1], image[2:, 1:-1])


def test_thin_geometry_makes_lines_one_pixel_thin():
    """Albedo at 64x64: pixels on lines one pixel thin are measured 6.5% of the film, 1.9% without the wires and
    leaves."""
    spec = get_scene("thin-geometry")
    bare = _without(spec, ("fence-wire", "fence-post", "power-line", "wire-sculpture", "crown", "bush"))
    fractions = []
    for scene in (spec, bare):
        buffers, _ = _load(scene, (64, 64)).render_aovs(16, 1)
        fractions.append(_thin_lines(luminance(buffers["albedo"].astype(np.float64)), 0.05).mean())
    thin, without = fractions
    assert thin > 0.04 and thin > 2.5 * without, fractions


def test_glass_caustic_has_caustic_light_at_depth_four_where_the_optics_put_it():
    """Path classes at 48x48, 128 spp: the caustic carries 4.9% of the light at depth 5 and 0.02% (reflections
    off the glass only) at depth 3; its brightest pixel is where the sphere focuses the light."""
    scene = _load("glass-caustic", (48, 48), 5)
    shares, images = {}, {}
    for depth in (3, 5):
        images[depth], nonfinite = scene.render_path_classes(128, depth, 1)
        assert nonfinite == 0
        caustic = luminance(images[depth]["caustic"].astype(np.float64))
        shares[depth] = caustic.sum() / luminance(images[depth]["total"].astype(np.float64)).sum()
    assert shares[5] > 0.01 and shares[5] > 20 * shares[3], shares
    caustic = luminance(images[5]["caustic"].astype(np.float64))
    smoothed = sum(np.roll(np.roll(caustic, dy, 0), dx, 1) for dy in (-1, 0, 1) for dx in (-1, 0, 1))
    row, column = np.unravel_index(np.argmax(smoothed), smoothed.shape)
    expected = _pixel(get_scene("glass-caustic").camera, standard_scenes.caustic_center(), (48, 48))
    assert np.hypot(row + 0.5 - expected[0], column + 0.5 - expected[1]) < 3.0, ((row, column), expected)
