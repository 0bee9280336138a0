"""The scene files in a user's style under examples/: sparselt's path estimator agrees with Mitsuba's own path
integrator on the features each adds.

- ``atelier-scene``: a directional sun, a disk light, a box pixel filter, the procedural checkerboard, an OBJ with
  its own normals and texture coordinates, thin glass.
- ``dusk-scene``: an HDR environment map with a small bright sun, a spot light, a point light, an area emitter
  whose radiance is a bitmap, a bump map, the principled BSDF, a binary PLY mesh, smooth plastic, solid glass, the
  default Gaussian pixel filter.

Real Mitsuba renders at a small size, fixed seeds; bounds from the passes' standard errors.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sparselt.rendering.layout import path_layout
from sparselt.rendering.scenes import get_scene

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
#: (folder, the path kind's depth in its suite.toml)
SCENES = (("atelier-scene", 5), ("dusk-scene", 6))
PASSES = 6
SPP = 128
#: Pixels that see only emitters are the same in every pass (a standard error of 0); their two renders differ by
#: float rounding, so each pixel's standard error is at least this fraction of its value.
ROUNDING = 1e-4


@pytest.fixture(scope="module", params=SCENES, ids=[name for name, _ in SCENES])
def passes(request):
    from sparselt.rendering.mitsuba import MitsubaScene

    name, depth = request.param
    scene = MitsubaScene(get_scene(str(EXAMPLES / name / "scene.xml")), (32, 24))
    ours = np.array([scene.render_estimator(path_layout("path", depth), SPP, 10 + index)[0]
                     for index in range(PASSES)], dtype=np.float64)
    theirs = np.array([scene.render_path(SPP, depth, 100 + index)[0] for index in range(PASSES)], dtype=np.float64)
    return ours, theirs


def test_the_path_estimator_matches_mitsubas_path_integrator(passes):
    """The image means agree within 4 standard errors of their difference (a missed light, or a material or
    texture evaluated differently, would change the mean by far more), and per pixel the differences look like
    noise: at most 1% of the pixels beyond 4 standard errors."""
    ours, theirs = passes
    per_pass = ours.mean(axis=(1, 2, 3)), theirs.mean(axis=(1, 2, 3))
    difference = per_pass[0].mean() - per_pass[1].mean()
    error = np.sqrt(per_pass[0].var(ddof=1) / PASSES + per_pass[1].var(ddof=1) / PASSES)
    assert per_pass[1].mean() > 0.05
    assert abs(difference) < 4 * error, (difference, error)
    mean = theirs.mean(axis=0)
    pixel_error = np.maximum(np.sqrt(ours.var(axis=0, ddof=1) / PASSES + theirs.var(axis=0, ddof=1) / PASSES),
                             ROUNDING * np.abs(mean))
    z = (ours.mean(axis=0) - mean) / np.maximum(pixel_error, 1e-12)
    assert np.mean(np.abs(z) > 4) <= 0.01
