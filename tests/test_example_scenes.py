"""The scene files in a user's style under examples/: sparselt's path estimator agrees with Mitsuba's own path
integrator on the features each adds.

- ``atelier-scene``: a directional sun, a disk light, a box pixel filter, the procedural checkerboard, an OBJ with
  its own normals and texture coordinates, thin glass.
- ``dusk-scene``: an HDR environment map with a small bright sun, a spot light, a point light, an area emitter
  whose radiance is a bitmap, a bump map, the principled BSDF, a binary PLY mesh, smooth plastic, solid glass, the
  default Gaussian pixel filter.
- ``greenhouse-scene``: Mitsuba's analytic sun and sky (``sunsky``), alpha-cut leaves (a ``mask`` BSDF with a bitmap
  opacity over a two-sided textured diffuse) as instances of a shape group, a normal map, a blend BSDF with a bitmap
  weight, a rough dielectric, an anisotropic rough conductor, a cylinder, a tent pixel filter.
- ``workshop-scene``: included lights (an area light whose radiance is an HDR bitmap, a sphere light whose radiance
  is a spectrum given per wavelength, a rectangle light facing down by ``flip_normals``, a ``projector``), B-spline
  curves with the ``hair`` BSDF, a ``conductor`` whose specular reflectance is a bitmap, ``pplastic``, a two-sided
  BSDF with two different sides, the ``null`` BSDF, an OBJ with face normals, a principal point offset, an RGBA film
  with a Gaussian pixel filter, a stratified sampler, a second sensor.

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
SCENES = (("atelier-scene", 5), ("dusk-scene", 6), ("greenhouse-scene", 5), ("workshop-scene", 5))
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


def test_instanced_shapes_leave_the_soft_shadow_inputs_whole():
    """greenhouse-scene's leaves are instances of a shape group, which have no surface area: the light sample's
    light size (``sqrt(A) / 2`` of its emitter's shape) comes from a table read on the host, so the auxiliary
    outputs and the filters' statistics work there. Where the lamp (a 0.24 x 0.16 rectangle) was sampled it is
    its ``sqrt(A) / 2``; for the sun and sky (no shape) 0; both kinds of sample occur."""
    import math

    from sparselt.rendering.mitsuba import MitsubaScene

    scene = MitsubaScene(get_scene(str(EXAMPLES / "greenhouse-scene" / "scene.xml")), (24, 16))
    layout = path_layout("path", 3)
    grid = (24, 16) + (4,) * (len(layout.dimensions) - 2)
    _, _, _, auxiliary = scene.sample_pixels(layout, grid, 16, 5, auxiliary=("light_distance", "light_size"))
    sampled = auxiliary["light_size"][np.isfinite(auxiliary["light_distance"])]
    lamp = math.sqrt(0.24 * 0.16) / 2
    assert np.all(np.isclose(sampled, lamp, rtol=1e-5) | (sampled == 0.0))
    assert 0 < np.mean(sampled > 0) < 1
    statistics, _ = scene.sample_pixel_statistics(layout, grid, 5, ("rgb", "least_penumbra"), spp=4)
    assert np.all(np.isfinite(statistics["rgb"])) and np.isfinite(statistics["least_penumbra"]).any()


def test_no_ray_reads_past_the_end_of_a_curves_segment_table():
    """Mitsuba 3.9 reads one element past a ``bsplinecurve``'s segment table on hits within float32 rounding of
    the last segment's end, and the garbage it reads can crash the process: ``pt`` on the workshop scene's
    indirect kind at 64 spp and seed 2^30 died with a segmentation fault. With Dr.Jit's bounds checks on (debug
    mode, in a fresh process) that render reports no out-of-bounds read now (it reported one before
    :func:`sparselt.rendering.mitsuba.integrand.intersect` kept the curve parameter off the end)."""
    import subprocess
    import sys

    script = (
        "import drjit as dr\n"
        "from sparselt.rendering.layout import path_layout\n"
        "from sparselt.rendering.mitsuba import MitsubaScene\n"
        "from sparselt.rendering.scenes import get_scene\n"
        f"scene = MitsubaScene(get_scene({str(EXAMPLES / 'workshop-scene' / 'scene.xml')!r}), (200, 136))\n"
        "dr.set_flag(dr.JitFlag.Debug, True)\n"
        "image, _ = scene.render_estimator(path_layout('indirect', 3), 64, 1 << 30)\n"
        "print('mean', float(image.mean()))\n")
    finished = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=600)
    assert finished.returncode == 0, finished.stderr[-2000:]
    assert "mean" in finished.stdout
    assert "out-of-bounds" not in finished.stderr + finished.stdout, (finished.stderr + finished.stdout)[-2000:]
