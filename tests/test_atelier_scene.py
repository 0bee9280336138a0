"""The second scene file in a user's style (examples/atelier-scene): sparselt's path estimator agrees with
Mitsuba's own path integrator on the features it adds (a directional sun, a disk light, a box pixel filter, the
procedural checkerboard, an OBJ with its own normals and texture coordinates, thin glass).

Real Mitsuba renders at a small size, fixed seeds; bounds from the passes' standard errors.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sparselt.rendering.layout import path_layout
from sparselt.rendering.scenes import get_scene

ATELIER = Path(__file__).resolve().parents[1] / "examples" / "atelier-scene" / "scene.xml"
PASSES = 6
SPP = 128


@pytest.fixture(scope="module")
def passes():
    from sparselt.rendering.mitsuba import MitsubaScene

    scene = MitsubaScene(get_scene(str(ATELIER)), (32, 24))
    ours = np.array([scene.render_estimator(path_layout("path", 5), SPP, 10 + index)[0] for index in range(PASSES)],
                    dtype=np.float64)
    theirs = np.array([scene.render_path(SPP, 5, 100 + index)[0] for index in range(PASSES)], dtype=np.float64)
    return ours, theirs


def test_the_path_estimator_matches_mitsubas_path_integrator_on_the_atelier(passes):
    """The image means agree within 4 standard errors of their difference (a missed directional light or disk
    light would change the mean by far more), and per pixel the differences look like noise: at most 1% of the
    pixels beyond 4 standard errors."""
    ours, theirs = passes
    per_pass = ours.mean(axis=(1, 2, 3)), theirs.mean(axis=(1, 2, 3))
    difference = per_pass[0].mean() - per_pass[1].mean()
    error = np.sqrt(per_pass[0].var(ddof=1) / PASSES + per_pass[1].var(ddof=1) / PASSES)
    assert per_pass[1].mean() > 0.05
    assert abs(difference) < 4 * error, (difference, error)
    pixel_error = np.sqrt(ours.var(axis=0, ddof=1) / PASSES + theirs.var(axis=0, ddof=1) / PASSES)
    z = (ours.mean(axis=0) - theirs.mean(axis=0)) / np.maximum(pixel_error, 1e-12)
    assert np.mean(np.abs(z) > 4) <= 0.01
