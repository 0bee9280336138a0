"""Radiance per path class (`render_path_classes`) and the caustic mask built on it, for any scene.

Small films of real scenes, fixed seeds. The total must be an unbiased
estimate of Mitsuba's own ``path`` integrator; the caustic part must vanish
where no specular BSDF is, and lie where the scenes' caustics are.
"""

import json
from dataclasses import replace

import numpy as np
import pytest

from sparselt.experiments.compare import ComparisonConfig, compare
from sparselt.experiments.quality import caustic_mask
from sparselt.images import luminance
from sparselt.rendering.mitsuba import count_samples, path_classes
from sparselt.rendering.mitsuba.path_classes import PATH_CLASSES
from sparselt.rendering.scenes import get_scene
from sparselt.rendering.setup import SceneSetup

RESOLUTION = (32, 32)
MAX_DEPTH = 5

#: A diffuse plane, a glass sphere above it and a small spherical light: the sphere focuses the light into a
#: caustic on the plane, in the sphere's shadow.
XML = """<scene version="3.0.0">
  <sensor type="perspective">
    <float name="fov" value="40"/>
    <transform name="to_world"><lookat origin="0, 4, 4" target="0, 0, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="32"/><integer name="height" value="32"/></film>
  </sensor>
  <shape type="rectangle">
    <transform name="to_world"><scale value="3"/><rotate x="1" angle="-90"/></transform>
    <bsdf type="diffuse"><rgb name="reflectance" value="0.6"/></bsdf>
  </shape>
  <shape type="sphere">
    <point name="center" x="0" y="0.8" z="0"/><float name="radius" value="0.6"/>
    <bsdf type="dielectric"/>
  </shape>
  <shape type="sphere">
    <point name="center" x="0.6" y="3.5" z="-0.6"/><float name="radius" value="0.15"/>
    <emitter type="area"><rgb name="radiance" value="60"/></emitter>
  </shape>
</scene>
"""


def _scene(name, resolution=RESOLUTION):
    return SceneSetup(name, max_depth=MAX_DEPTH).load(resolution).scene


@pytest.fixture(scope="module")
def caustics():
    return _scene("cornell-caustics")


@pytest.fixture(scope="module")
def xml_scene(tmp_path_factory):
    path = tmp_path_factory.mktemp("xml") / "glass-sphere.xml"
    path.write_text(XML)
    return str(path)


@pytest.fixture(scope="module", params=["pinhole", "thin-lens", "scene-file-hiding-emitters"])
def unbiased_case(request, tmp_path_factory):
    """A scene and the depth to compare at: cornell-caustics through a pinhole and a thin lens, and the scene
    file with ``hide_emitters`` (its light would be seen directly)."""
    if request.param == "scene-file-hiding-emitters":
        path = tmp_path_factory.mktemp("hidden") / "hidden.xml"
        path.write_text(XML.replace("<sensor", '<integrator type="path"><boolean name="hide_emitters" '
                                              'value="true"/></integrator>\n  <sensor', 1))
        loaded = SceneSetup(scene=str(path), max_depth=4).load(RESOLUTION).scene
        assert loaded.spec.hide_emitters
        return loaded, 4
    aperture = 0.05 if request.param == "thin-lens" else None
    loaded = SceneSetup("cornell-caustics", max_depth=MAX_DEPTH, aperture=aperture).load(RESOLUTION).scene
    assert loaded.camera.thin_lens == (aperture is not None)
    return loaded, MAX_DEPTH


def test_the_total_is_unbiased_for_mitsubas_path_integrator(unbiased_case):
    """Means over 4x4-pixel blocks and over the image, per channel, from sixteen independent 16-spp renders of
    each: Welch's statistic of every difference below 6 (192 of them: a t with about 30 degrees of freedom passes
    6 with probability 5e-6 each), and its mean absolute value near that of a standard normal (0.8; measured
    0.6 to 1.0 with the largest 2.3 to 4.9 over three seed sets per case)."""
    scene, depth = unbiased_case
    seeds = range(1, 17)
    ours = np.array([scene.render_path_classes(16, depth, seed)[0]["total"] for seed in seeds], dtype=np.float64)
    theirs = np.array([scene.render_path(16, depth, 100 + seed)[0] for seed in seeds], dtype=np.float64)

    def blocks(images):
        return images.reshape(len(images), 8, 4, 8, 4, 3).mean(axis=(2, 4)).reshape(len(images), -1)

    statistics = []
    for a, b in ((blocks(ours), blocks(theirs)), (ours.mean(axis=(1, 2)), theirs.mean(axis=(1, 2)))):
        error = np.sqrt(a.var(axis=0, ddof=1) / len(a) + b.var(axis=0, ddof=1) / len(b))
        difference = a.mean(axis=0) - b.mean(axis=0)
        assert np.all((error > 0) | (difference == 0))
        statistics.append(np.abs(difference) / np.where(error > 0, error, 1.0))
    statistics = np.concatenate(statistics)
    assert statistics.max() < 6.0 and statistics.mean() < 1.2, (statistics.max(), statistics.mean())


def test_images_shapes_seeds_and_sample_count(caustics):
    with count_samples() as count:
        images, nonfinite = caustics.render_path_classes(4, MAX_DEPTH, 3)
    assert count.path_samples == 32 * 32 * 4 and nonfinite == 0
    assert tuple(images) == PATH_CLASSES
    for image in images.values():
        assert image.shape == (32, 32, 3) and image.dtype == np.float32 and np.all(np.isfinite(image))
    assert np.all(images["caustic"] >= 0) and np.all(images["caustic"] <= images["total"] * (1 + 1e-6))
    again, _ = caustics.render_path_classes(4, MAX_DEPTH, 3)
    other, _ = caustics.render_path_classes(4, MAX_DEPTH, 4)
    assert np.array_equal(again["total"], images["total"]) and not np.array_equal(other["total"], images["total"])
    # A seed beyond 32 bits is folded by the launch seam like every other render's.
    large, _ = caustics.render_path_classes(4, MAX_DEPTH, 2**40 + 3)
    assert np.all(np.isfinite(large["total"]))


def test_the_images_do_not_depend_on_the_pieces_the_render_runs_in(caustics, monkeypatch):
    whole, _ = caustics.render_path_classes(8, MAX_DEPTH, 5)
    monkeypatch.setattr(path_classes, "LANES_PER_KERNEL", 8 * 100)  # 100 pixels per kernel: 11 pieces, the last short
    pieces, _ = caustics.render_path_classes(8, MAX_DEPTH, 5)
    for name in PATH_CLASSES:
        assert np.array_equal(whole[name], pieces[name]), name


@pytest.mark.parametrize("spp, max_depth, error", [(0, 3, ValueError), (4, 0, ValueError), (2.0, 3, TypeError),
                                                   (4, True, TypeError)])
def test_bad_arguments_are_refused(caustics, spp, max_depth, error):
    with pytest.raises(error, match="spp|max_depth"):
        caustics.render_path_classes(spp, max_depth, 0)


def test_a_scene_without_specular_bsdfs_has_no_caustic_radiance():
    images, _ = _scene("cornell-box").render_path_classes(64, MAX_DEPTH, 1)
    assert luminance(images["total"]).mean() > 0.05
    assert np.all(images["caustic"] == 0.0)


def test_depth_one_and_two_have_no_caustics(caustics):
    """A caustic path ``L S D E`` has at least 3 segments."""
    for depth in (1, 2):
        images, _ = caustics.render_path_classes(16, depth, 1)
        assert np.all(images["caustic"] == 0.0), depth
    images, _ = caustics.render_path_classes(16, 3, 1)
    assert images["caustic"].max() > 0


def test_the_cornell_caustics_mask_holds_the_glass_spheres_focus_on_the_floor():
    """At 64x64 and 256 spp the brightest caustic region is the glass sphere's focus on the floor (lower image
    quarter, right of centre; measured 8 to 11 pixels of caustic luminance > 0.3 over seeds 1-3, all in the
    mask; the mask 163 to 181 pixels, the rest the gold sphere's dimmer caustics)."""
    scene = _scene("cornell-caustics", (64, 64))
    reference, _ = scene.render_path(256, MAX_DEPTH, 1000)
    mask = caustic_mask(scene, reference, spp=256, max_depth=MAX_DEPTH, seed=1)
    assert mask.shape == (64, 64) and mask.dtype == bool
    assert 20 <= mask.sum() <= 0.1 * mask.size, mask.sum()
    images, _ = scene.render_path_classes(256, MAX_DEPTH, 1)
    focus = luminance(images["caustic"]) > 0.3
    assert focus.sum() >= 4, focus.sum()
    rows, columns = np.nonzero(focus)
    assert rows.min() >= 48 and columns.min() >= 32  # on the floor, under the glass sphere (right)
    assert mask[focus].all()


def test_the_sunlit_rooms_sunlit_patch_is_in_the_mask():
    """Every sunlit path crosses the pane (a thin dielectric: a delta vertex), so the sunlit floor is caustic;
    the pane itself (the sky seen through glass, ``L S E``) is not, and without the pane nothing is.

    The patch is where the open window's render is bright (as in test_sunlit_scene.py). At 1024 spp the mask
    holds measured 90 to 93% of it over seeds 1-3 (a pixel whose samples all miss the sun keeps only
    non-caustic light in its estimate: the ratio is as noisy as the caustic), and none of the pane.
    """
    spec = get_scene("sunlit-room")
    open_window = replace(spec, name="sunlit-room-open-window",
                          objects={key: value for key, value in spec.objects.items() if key != "window-pane"})
    opened = SceneSetup(open_window.name, max_depth=MAX_DEPTH, scene_spec=open_window).load(RESOLUTION).scene
    patch = luminance(opened.render_path(256, MAX_DEPTH, 1000)[0]) > 0.5
    assert 10 <= patch.sum(), patch.sum()  # measured 30 of 1024 pixels
    assert np.all(opened.render_path_classes(64, MAX_DEPTH, 1)[0]["caustic"] == 0.0)

    glass = _scene("sunlit-room")
    reference, _ = glass.render_path(256, MAX_DEPTH, 1000)
    mask = caustic_mask(glass, reference, spp=1024, max_depth=MAX_DEPTH, seed=1)
    assert mask[patch].mean() > 0.75, mask[patch].mean()
    # Depth 2 sees light only through the pane (no shadow ray leaves the closed room): those pixels are the pane.
    pane = luminance(glass.render_path(16, 2, 1)[0]) > 0
    assert pane.sum() >= 10 and mask[pane].mean() < 0.1, (pane.sum(), mask[pane].mean())


def test_a_scene_file_gets_a_caustic_mask(xml_scene):
    scene = SceneSetup(scene=xml_scene, kind="path", max_depth=4).load(RESOLUTION).scene
    images, _ = scene.render_path_classes(128, 4, 1)
    assert images["caustic"].max() > 0
    reference, _ = scene.render_path(128, 4, 7)
    mask = caustic_mask(scene, reference, spp=128, max_depth=4, seed=1)
    assert 1 <= mask.sum() <= 0.05 * mask.size, mask.sum()  # the focus under the sphere, a few pixels
    assert luminance(images["caustic"])[mask].min() > 0


def test_compare_reports_the_caustic_mask_of_a_scene_file(tmp_path, xml_scene):
    config = ComparisonConfig(scene=xml_scene, kind="path", shape=RESOLUTION + (2,) * 12, methods=("pt",),
                              spps=(2,), seeds=(1,), reference_spp=64, max_depth=4, timing_repeats=1,
                              caustic_mask=True)
    compare(config, tmp_path / "run", progress=False, cache_directory=str(tmp_path / "cache"))
    record = json.loads((tmp_path / "run" / "compare.json").read_text())
    assert record["caustic_mask_pixels"] >= 1
    assert (tmp_path / "run" / "images" / "caustic_mask.png").exists()
    rows = (tmp_path / "run" / "results.csv").read_text()
    assert "relmse_caustic" in rows.splitlines()[0]


def test_the_mask_refuses_bad_arguments(caustics):
    reference = np.ones((32, 32, 3))
    for fraction in (-0.1, 1.0):
        with pytest.raises(ValueError, match="fraction"):
            caustic_mask(caustics, reference, spp=1, max_depth=3, fraction=fraction)
    with pytest.raises(TypeError, match="fraction"):
        caustic_mask(caustics, reference, spp=1, max_depth=3, fraction="0.3")
    with pytest.raises(ValueError, match="reference has shape"):
        caustic_mask(caustics, np.ones((16, 32, 3)), spp=1, max_depth=3)
