"""The `sunlit-room` scene: sunlight through window glass, a caustic path tracing finds only by chance (issue 35).

Small films of the real scene, fixed seeds. The bounds are conservative
against the values measured when the tests were written (quoted beside each).
"""

from dataclasses import replace

import numpy as np
import pytest

from sparselt.analysis.metrics import relative_mean_squared_error
from sparselt.cli import main
from sparselt.images import luminance
from sparselt.rendering import procedural
from sparselt.rendering.scenes import SCENES, get_scene, scene_names
from sparselt.rendering.setup import SceneSetup

NAME = "sunlit-room"
RESOLUTION = (64, 64)
MAX_DEPTH = 5
SEEDS = tuple(range(1, 7))
SPP = 256


def _luminances(scene, spp, seeds):
    return np.array([luminance(scene.render_path(spp, MAX_DEPTH, seed)[0].astype(np.float64)) for seed in seeds])


@pytest.fixture(scope="module")
def rooms():
    """The room with its glass pane, and the same room with the pane removed (an open window), at 64x64."""
    spec = get_scene(NAME)
    open_window = replace(spec, name=NAME + "-open-window",
                          objects={key: value for key, value in spec.objects.items() if key != "window-pane"})
    glass = SceneSetup(NAME, max_depth=MAX_DEPTH).load(RESOLUTION).scene
    opened = SceneSetup(open_window.name, max_depth=MAX_DEPTH, scene_spec=open_window).load(RESOLUTION).scene
    return glass, opened


@pytest.fixture(scope="module")
def patch(rooms):
    """Pixels of the sunlit floor patch, and the open window's 1024-spp luminance there (its reference)."""
    _, opened = rooms
    reference = _luminances(opened, 1024, (1000,))[0]
    mask = reference > 0.5  # sunlit pixels (the floor patch is about 0.78); the rest has bounced light only
    return mask, reference


@pytest.fixture(scope="module")
def renders(rooms):
    """Both rooms at equal spp over the same seeds: luminance images, shape (seeds, height, width)."""
    glass, opened = rooms
    return _luminances(glass, SPP, SEEDS), _luminances(opened, SPP, SEEDS)


def test_it_is_a_listed_built_in_scene(capsys):
    assert NAME in scene_names() and NAME in SCENES
    assert main(["scenes"]) == 0
    assert NAME in capsys.readouterr().out
    spec = get_scene(NAME)
    assert spec.name == NAME and spec.filename is None and tuple(spec.default_resolution) == (128, 128)
    assert not spec.camera.thin_lens
    assert spec.objects["window-pane"]["bsdf"]["type"] == "thindielectric"
    assert spec.objects["sun"]["emitter"]["type"] == "area" and spec.objects["sky"]["type"] == "constant"
    # The sun's light falls through the window onto the floor inside the room.
    corners = procedural.sunlit_patch_corners()
    assert np.allclose(corners[:, 1], 0.0)
    assert np.all(np.abs(corners[:, 0]) < procedural.ROOM_HALF_WIDTH)
    assert np.all(np.abs(corners[:, 2]) < procedural.ROOM_HALF_DEPTH)


def test_renders_finite_images_for_path_indirect_and_dof():
    path = SceneSetup(NAME, kind="path", max_depth=MAX_DEPTH, shape=(32, 32) + (2,) * 16).load()
    image, _ = path.scene.render_path(4, MAX_DEPTH, 1)
    assert image.shape == (32, 32, 3) and np.all(np.isfinite(image)) and image.min() >= 0 and image.max() > 0
    for setup in (SceneSetup(NAME, kind="indirect", max_depth=MAX_DEPTH, shape=(32, 32, 4, 4)),
                  SceneSetup(NAME, kind="dof", max_depth=MAX_DEPTH, shape=(32, 32, 4, 4), aperture=0.05)):
        loaded = setup.validate().load()
        estimate, nonfinite = loaded.scene.render_estimator(loaded.layout, 4, 2)
        assert estimate.shape == (32, 32, 3) and np.all(np.isfinite(estimate)), setup.kind
        assert estimate.min() >= 0 and estimate.max() > 0 and nonfinite == 0, setup.kind
    # --aperture alone focuses on the floor where the central ray lands, inside the room.
    assert loaded.thin_lens and 1.0 < loaded.scene.camera.focus_distance < 8.0


def test_the_glass_transmits_most_of_the_sunlight(renders, patch):
    """Equal spp: the patch's mean luminance with the glass is that of the open window times the pane's
    transmittance (about 0.91 at this incidence; measured 0.92 +- 0.06 over these seeds)."""
    glass, opened = renders
    mask, _ = patch
    assert 100 < mask.sum() < 400  # measured 142 of 4096 pixels
    glass_means = glass[:, mask].mean(axis=1)  # one independent estimate per seed
    ratio = glass_means.mean() / opened[:, mask].mean()
    standard_error = glass_means.std(ddof=1) / np.sqrt(len(SEEDS)) / opened[:, mask].mean()
    assert 0.6 < ratio < 1.0 + 4.0 * standard_error, (ratio, standard_error)


def test_the_sunlit_patch_is_a_caustic_for_path_tracing(renders, patch):
    """Per-pixel relative variance in the patch at equal spp: glass over open window, measured 650."""
    glass, opened = renders
    mask, reference = patch

    def relative_variance(images):
        return float(np.mean(images.var(axis=0, ddof=1)[mask] / reference[mask] ** 2))

    ratio = relative_variance(glass) / relative_variance(opened)
    assert ratio > 50.0, ratio


def test_path_tracing_error_is_far_above_the_cornell_box_at_equal_spp():
    """relMSE at 16 spp (mean over seeds) against a 1024-spp render: measured 80 here (18 to 162 per seed), 0.020
    on the Cornell box.

    One seed alone can miss the sun entirely at a few spp (a relMSE near 0.1 at 4 spp was seen): the
    error's distribution over seeds is heavy-tailed, so the mean over seeds is compared.
    """
    errors = {}
    for name in (NAME, "cornell-box"):
        scene = SceneSetup(name, max_depth=MAX_DEPTH).load(RESOLUTION).scene
        reference = scene.render_path(1024, MAX_DEPTH, 500)[0].astype(np.float64)
        images = [scene.render_path(16, MAX_DEPTH, seed)[0].astype(np.float64) for seed in (1, 2, 3, 4)]
        errors[name] = np.mean([relative_mean_squared_error(image, reference) for image in images])
    assert errors["cornell-box"] < 0.1, errors
    assert errors[NAME] > 100.0 * errors["cornell-box"], errors
