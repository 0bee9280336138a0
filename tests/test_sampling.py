"""The sampled signals integrate to Mitsuba's own path tracer, converge, and are reproducible.

Scenes are the real Cornell box rendered by Mitsuba at small resolution.
Bounds: the image mean of the 32x32 Cornell box varies by about 1% between
seeds at 10^6 samples (measured: the light's edge and next-event estimation
close to the light give rare large values), so each comparison uses 1.6x10^7
samples on each side: a standard error of about 0.25% per side and 0.35% for
the comparison, against which 2% is more than five standard errors. The
native references of different depths share a seed, so their difference (the
indirect part) is not swamped by the noise of the direct part.
"""

import dataclasses
import math

import numpy as np
import pytest

from sparselt.rendering.acquire import AcquisitionConfig, acquire_signal
from sparselt.rendering.layout import path_layout
from sparselt.rendering.mitsuba import MitsubaScene

WIDTH = 32


@pytest.fixture(scope="module")
def cornell_scene(cornell):
    return MitsubaScene(cornell, (WIDTH, WIDTH))


@pytest.fixture(scope="module")
def cornell_lens_scene(cornell):
    return MitsubaScene(cornell.with_lens(0.08, 3.5), (WIDTH, WIDTH))


@pytest.fixture(scope="module")
def native(cornell_scene):
    """Mitsuba path integrator images at depths 2, 3, 4 with 16384 spp, one seed."""
    return {depth: cornell_scene.render_path(16384, depth, seed=1)[0].astype(np.float64) for depth in (2, 3, 4)}


def _channel_error(image, reference):
    return np.abs(image.mean(axis=(0, 1)) / reference.mean(axis=(0, 1)) - 1.0)


def _signal_image(scene, kind, depth, shape, spp, seed=7):
    layout = path_layout(kind, depth, thin_lens=scene.camera.thin_lens)
    cells = math.prod(shape)
    means, nonfinite = scene.sample_cells(layout, shape, 0, cells, spp, seed)
    assert nonfinite.sum() == 0
    data = means.reshape(shape + (3,)).astype(np.float64)
    return data.reshape(shape[0], shape[1], -1, 3).mean(axis=2).transpose(1, 0, 2)


def test_path_signal_integrates_to_mitsuba_path(cornell_scene, native):
    shape = (WIDTH, WIDTH) + (2,) * 8
    image = _signal_image(cornell_scene, "path", 3, shape, spp=64)
    assert image.shape == (WIDTH, WIDTH, 3)
    assert np.all(_channel_error(image, native[3]) < 0.02)


def test_dof_signal_integrates_to_mitsuba_path_on_the_same_thin_lens(cornell_lens_scene):
    reference = cornell_lens_scene.render_path(16384, 3, seed=11)[0].astype(np.float64)
    image = _signal_image(cornell_lens_scene, "dof", 3, (WIDTH, WIDTH, 16, 16), spp=64)
    assert np.all(_channel_error(image, reference) < 0.02)


def test_indirect_signal_is_path_minus_direct(cornell_scene, native):
    image = _signal_image(cornell_scene, "indirect", 3, (WIDTH, WIDTH, 16, 16), spp=64)
    expected = native[3] - native[2]
    # The indirect part is ~17% of the image: the same absolute noise is a larger relative one.
    assert np.all(_channel_error(image, expected) < 0.05)
    # And it carries no direct light: far below the full image.
    assert np.all(image.mean(axis=(0, 1)) < 0.5 * native[3].mean(axis=(0, 1)))


def test_path_indirect_signal_is_paths_of_length_three_and_four(cornell_scene, native):
    image = _signal_image(cornell_scene, "path-indirect", 3, (WIDTH, WIDTH) + (2,) * 8, spp=64)
    expected = native[4] - native[2]
    assert np.all(_channel_error(image, expected) < 0.05)


def test_pixel_error_falls_as_one_over_spp(cornell_scene):
    """Per-pixel MSE against a 16384-spp reference, at 8, 32 and 128 samples per pixel."""
    width = 16
    scene = cornell_scene
    small = MitsubaScene(scene.spec, (width, width))
    reference = small.render_path(16384, 3, seed=5)[0].astype(np.float64)
    shape = (width, width, 2, 2)
    samples_per_pixel = []
    errors = []
    for spp in (2, 8, 32):
        layout = path_layout("path", 3)
        # A 4-axis path signal is not a kind, so grid x, y and light1 (the others are random).
        layout = dataclasses.replace(layout, axes=("x", "y", "light1_u", "light1_v"))
        means, _ = small.sample_cells(layout, shape, 0, math.prod(shape), spp, 3)
        image = means.reshape(shape + (3,)).astype(np.float64).mean(axis=(2, 3)).transpose(1, 0, 2)
        samples_per_pixel.append(4 * spp)
        errors.append(np.mean((image - reference) ** 2))
    slope = np.polyfit(np.log(samples_per_pixel), np.log(errors), 1)[0]
    assert -1.25 < slope < -0.75, (samples_per_pixel, errors, slope)


def test_same_seed_same_signal_whatever_the_chunking(cornell):
    config = AcquisitionConfig(scene="cornell-box", kind="path", shape=(12, 10, 2, 2, 2, 2, 2, 2, 2, 2), spp=4, seed=3)
    one = acquire_signal(config, progress=False, chunk_cells=30720, scene_spec=cornell)
    many = acquire_signal(config, progress=False, chunk_cells=777, scene_spec=cornell)
    assert np.array_equal(one.data, many.data)
    other = acquire_signal(AcquisitionConfig(**{**config.__dict__, "seed": 4}), progress=False, scene_spec=cornell)
    assert not np.array_equal(one.data, other.data)
    # Statistically the same image, though.
    assert np.all(np.abs(one.image().mean(axis=(0, 1)) - other.image().mean(axis=(0, 1))) < 0.1 * one.image().mean(axis=(0, 1)))



def test_camera_rays_are_coherent_packets_except_behind_a_wide_lens():
    """Embree's coherent mode for camera rays (issue 24): pinholes and narrow lenses yes, dof-sculptures' lens no."""
    from sparselt.rendering.mitsuba import coherent_camera_rays
    from sparselt.rendering.scenes import get_scene

    assert coherent_camera_rays(get_scene("cornell-box").camera)
    assert coherent_camera_rays(get_scene("cornell-box").with_lens(0.05, 4.0).camera)
    assert not coherent_camera_rays(get_scene("dof-sculptures").camera)
