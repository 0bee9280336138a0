"""Guided rendering throughput against Mitsuba's native ``path`` (issue target: >= 0.8x).

Renders the same film, depth and spp with ``MitsubaScene.render_guided`` (a
random 4-D map over the dof grid, both modes) and with Mitsuba's ``path``
integrator, kernels warmed first, best of three; prints samples per second and
the ratio guided / native measured in this run.

    .venv/bin/python benchmarks/guided_throughput.py [--scene dof-sculptures] [--spp 64]
"""

from __future__ import annotations

import argparse

import numpy as np

from sparselt.guiding import ImportanceMap
from sparselt.measurement import best_time
from sparselt.methods import Budget, ComparisonContext
from sparselt.methods.guided import render_with_map
from sparselt.rendering.layout import path_layout
from sparselt.rendering.mitsuba import MitsubaScene
from sparselt.rendering.scenes import get_scene


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scene", default="dof-sculptures")
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--resolution", type=int, default=500, help="film width and height (map: half of it)")
    arguments = parser.parse_args()
    resolution = (arguments.resolution, arguments.resolution)
    spec = get_scene(arguments.scene)
    if not spec.camera.thin_lens:
        spec = spec.with_lens(0.1, None)
    scene = MitsubaScene(spec, resolution)
    grid = (arguments.resolution // 2, arguments.resolution // 2, 16, 16)
    context = ComparisonContext(scene=scene, layout=path_layout("dof", 3, thin_lens=True), kind="dof",
                                grid_shape=grid, resolution=resolution, max_depth=3)
    importance = ImportanceMap(np.random.default_rng(0).random(grid) ** 4, defensive=0.1)
    importance.level_tables()
    samples = resolution[0] * resolution[1] * arguments.spp
    native = best_time(lambda: scene.render_path(arguments.spp, 3, 1), 3)
    print(f"{arguments.scene} {resolution[0]}x{resolution[1]}, {arguments.spp} spp, depth 3, map {'x'.join(map(str, grid))}")
    print(f"  mitsuba path        {native:7.3f} s   {samples / native / 1e6:6.2f} M samples/s")
    for mode in ("per-pixel", "global"):
        guided = best_time(lambda: render_with_map(context, importance, Budget(arguments.spp, 1), mode), 3)
        ratio = native / guided
        print(f"  guided {mode:10s}  {guided:7.3f} s   {samples / guided / 1e6:6.2f} M samples/s   "
              f"ratio {ratio:.2f} (target >= 0.8: {'met' if ratio >= 0.8 else 'NOT met'})")


if __name__ == "__main__":
    main()
