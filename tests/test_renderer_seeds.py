"""The renderer's launch seam: any non-negative integer seed works, and every sample is counted there (issue 34).

A plug-in that renders with ``budget.seed + 7919`` used to crash inside
Mitsuba ("sample_tea_32(): incompatible function arguments") as soon as the
seed reached 2**32.
"""

import numpy as np
import pytest

from sparselt.guiding import ImportanceMap
from sparselt.rendering.layout import path_layout
from sparselt.rendering.mitsuba import (GRADIENT_SHIFTS, SEED_LIMIT, MitsubaScene, count_samples, fold_seed,
                                        gradient_paths, launch)
from sparselt.rendering.scenes import get_scene

WIDTH, HEIGHT = 10, 8


@pytest.fixture(scope="module")
def scene():
    return MitsubaScene(get_scene("cornell-box").with_lens(0.05, 4.0), (WIDTH, HEIGHT))


# --------------------------------------------------------------------------- the fold


@pytest.mark.parametrize("seed", [0, 1, 7919, 2**31, 0x5A5A5A5A, SEED_LIMIT - 1])
def test_seeds_below_two_to_the_32_are_unchanged(seed):
    assert SEED_LIMIT == 2**32
    assert fold_seed(seed) == seed and type(fold_seed(seed)) is int
    assert fold_seed(np.uint32(seed)) == seed and fold_seed(np.int64(seed)) == seed


def test_larger_seeds_fold_to_32_bits_deterministically():
    """Golden values: a changed fold would change every image rendered with such a seed."""
    golden = {2**32: 1739479842, 2**32 + 7919: 2837717234, 2**64: 3223734438, 2**70: 867021172}
    for seed, folded in golden.items():
        assert fold_seed(seed) == folded
        assert fold_seed(int(str(seed))) == folded  # a pure function of the value
    assert fold_seed(np.uint64(2**63 + 5)) == fold_seed(2**63 + 5)
    assert all(0 <= fold_seed(seed) < SEED_LIMIT for seed in (2**32, 2**63, 2**64 - 1, 2**64, 10**40))


def test_derived_seeds_stay_distinct():
    """``seed + k`` and ``seed * k`` for seeds past 2**32 do not collapse onto each other or onto their bases."""
    bases = [SEED_LIMIT - 1 + offset for offset in range(0, 1000)]
    derived = [base + 7919 for base in bases] + [base * 1000 + 3 for base in bases]
    folded = [fold_seed(seed) for seed in bases + derived]
    assert len(set(folded)) == len(folded)
    # Not a truncation: a seed past 2**32 does not reuse the low word's stream.
    assert fold_seed(2**32 + 7919) != 7919 and fold_seed(2**64 + 1) != fold_seed(1)


@pytest.mark.parametrize("seed, error", [
    (-1, ValueError), (-(2**40), ValueError), (1.0, TypeError), ("3", TypeError), (True, TypeError),
    (None, TypeError), (np.float64(2.0), TypeError),
])
def test_a_seed_that_is_not_a_non_negative_integer_is_refused_by_name(seed, error):
    with pytest.raises(error, match="seed must be a non-negative integer"):
        fold_seed(seed)


def test_launch_refuses_a_bad_seed_before_any_work_and_counts_nothing():
    calls = []
    with count_samples() as counted:
        with pytest.raises(ValueError, match="-5"):
            launch(calls.append, -5, path_samples=10)
        assert launch(lambda seed: seed, 2**40, path_samples=3) == fold_seed(2**40)
    assert calls == [] and counted.path_samples == 3


# --------------------------------------------------------------------------- real renders with large seeds


def test_sample_pixels_takes_seeds_past_two_to_the_32(scene):
    layout = path_layout("dof", 3, thin_lens=True)
    grid = (WIDTH, HEIGHT, 2, 2)
    seed = 2**32 - 1 + 7919  # a plug-in's budget.seed + 7919 at the harness's largest seed
    values, cells, _ = scene.sample_pixels(layout, grid, 2, seed)
    again, _, _ = scene.sample_pixels(layout, grid, 2, seed)
    folded, folded_cells, _ = scene.sample_pixels(layout, grid, 2, fold_seed(seed))
    assert values.shape == (WIDTH * HEIGHT * 2, 3) and np.all(np.isfinite(values)) and values.max() > 0
    assert values.tobytes() == again.tobytes() == folded.tobytes() and np.array_equal(cells, folded_cells)
    low_word, _, _ = scene.sample_pixels(layout, grid, 2, seed % SEED_LIMIT)
    assert low_word.tobytes() != values.tobytes()


def test_render_path_and_every_estimator_take_seeds_past_two_to_the_32(scene):
    layout = path_layout("dof", 3, thin_lens=True)
    grid = (WIDTH, HEIGHT, 2, 2)
    seed = 3 * 2**32 + 11
    image, seconds = scene.render_path(2, 3, seed)
    assert image.shape == (HEIGHT, WIDTH, 3) and seconds > 0
    assert image.tobytes() == scene.render_path(2, 3, fold_seed(seed))[0].tobytes()
    buffers, _ = scene.render_aovs(1, seed)
    assert buffers["albedo"].shape == (HEIGHT, WIDTH, 3)
    means, _ = scene.sample_cells(layout, grid, 0, 16, 2, seed)
    assert means.tobytes() == scene.sample_cells(layout, grid, 0, 16, 2, fold_seed(seed))[0].tobytes()
    sums = scene.sample_gradients(layout, grid, 1, seed, offsets=2).sums
    assert sums.shape == (HEIGHT, WIDTH, 3, 3)
    statistics, _ = scene.sample_pixel_statistics(layout, grid, seed, ("rgb", "nearest"), spp=1)
    assert statistics["rgb"].shape == (WIDTH * HEIGHT, 3)
    estimate, _ = scene.render_estimator(layout, 1, seed)
    assert estimate.shape == (HEIGHT, WIDTH, 3)


# --------------------------------------------------------------------------- counting in the seam


def test_the_seam_counts_every_path_sample_of_every_estimator(scene):
    layout = path_layout("dof", 3, thin_lens=True)
    grid = (WIDTH, HEIGHT, 2, 2)
    pixels = WIDTH * HEIGHT
    importance = ImportanceMap(np.ones(grid), defensive=0.5)
    tables, densities = importance.level_tables(), importance.cell_densities(0)
    lanes = (np.array([0, 0, 3, 7]), np.array([0, 5, 1, 2]))
    expected = {
        "cells": (lambda: scene.sample_cells(layout, grid, 4, 10, 3, 1), 30),
        "listed cells": (lambda: scene.sample_cells(layout, grid, 0, 0, 2, 1, cells=[5, 5, 9]), 6),
        "pixels": (lambda: scene.sample_pixels(layout, grid, 2, 1), 2 * pixels),
        "a run of pixels": (lambda: scene.sample_pixels(layout, grid, 3, 1, first_pixel=5, pixel_count=7), 21),
        "coarser pixels": (lambda: scene.sample_pixels(layout, grid, 2, 1, resolution=(5, 4)), 40),
        "explicit lanes": (lambda: scene.sample_pixels(layout, grid, 9, 1, lanes=lanes), 4),
        "statistics": (lambda: scene.sample_pixel_statistics(layout, grid, 1, ("rgb",), spp=2), 2 * pixels),
        "statistics of counts": (lambda: scene.sample_pixel_statistics(layout, grid, 1, ("rgb",), counts=np.bincount(
            lanes[0], minlength=pixels)), 4),
        "gradients": (lambda: scene.sample_gradients(layout, grid, 2, 1, offsets=4),
                      2 * gradient_paths(WIDTH, HEIGHT, 4)),
        "reconnected gradients": (lambda: scene.sample_gradients(layout, grid, 2, 1, shift="reconnection"),
                                  2 * gradient_paths(WIDTH, HEIGHT, 4)),
        "estimator": (lambda: scene.render_estimator(layout, 2, 1), 2 * pixels),
        "guided": (lambda: scene.render_guided(layout, grid, tables, densities, 2, 1, mode="global"), 2 * pixels),
        "path": (lambda: scene.render_path(3, 3, 1), 3 * pixels),
        "aov": (lambda: scene.render_aovs(2, 1), 0),
    }
    assert gradient_paths(WIDTH, HEIGHT, 4) == 5 * pixels - 2 * (WIDTH + HEIGHT)
    assert set(GRADIENT_SHIFTS) == {2, 4}
    with count_samples() as everything:
        for name, (render, paths) in expected.items():
            with count_samples() as counted:
                render()
            assert counted.path_samples == paths, name
            assert counted.feature_samples == (2 * pixels if name == "aov" else 0), name
    assert everything.path_samples == sum(paths for _, paths in expected.values())
    assert everything.feature_samples == 2 * pixels
