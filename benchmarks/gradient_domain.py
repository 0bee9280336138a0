"""Gradient-domain path tracing: what the offset paths cost, and the reconstructions' time (issue 23).

Kernels warmed first, medians of ``--repeats`` runs with different seeds,
interleaved per seed so that a slow spell of the shared machine hits every
variant alike, in the same run:

- ``pt``: the baseline at the same spp (Mitsuba's path integrator; the kind's
  own estimator for indirect light);
- ``base``: the base paths alone, drawn by the same sampler kernel reduced per
  pixel (:meth:`MitsubaScene.sample_pixel_statistics` with ``rgb`` only);
- ``gradient``: :meth:`MitsubaScene.sample_gradients` with 4 offsets (and 2),
  the base paths and their one-pixel shifts in one launch.

The offsets' cost is ``(gradient - base) / base`` per base sample. Target:
at most 4x a base sample (four offsets; each costs what a base path costs when
it replays the same numbers). The same against ``pt``: ``(gradient - pt) / pt``.

Then the reconstructions at 512x512 RGB (random data; their time does not
depend on it): the screened Poisson L2 solve (target: at most 0.1 s) and one
iteration of the L1 ADMM (its default stop takes 3-20 on rendered images).

    .venv/bin/python benchmarks/gradient_domain.py [--spp 16,64] [--repeats 5]
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from sparselt.methods import Budget, ComparisonContext, get_method, run_timed, warm_up
from sparselt.recovery.poisson import screened_poisson, screened_poisson_l1
from sparselt.rendering.layout import path_layout
from sparselt.rendering.mitsuba import MitsubaScene
from sparselt.rendering.scenes import get_scene

CASES = (("cornell-box", "path", 3), ("courtyard", "indirect", 3), ("cornell-caustics", "path", 5))
OFFSET_TARGET = 4.0
L2_TARGET = 0.1


def _timed(function):
    start = time.perf_counter()
    function()
    return time.perf_counter() - start


def _sampling(arguments):
    size = arguments.resolution
    for scene_name, kind, depth in CASES:
        scene = MitsubaScene(get_scene(scene_name), (size, size))
        layout = path_layout(kind, depth)
        grid = (size, size) + (2,) * (len(layout.axes) - 2)
        context = ComparisonContext(scene=scene, layout=layout, kind=kind, grid_shape=grid, resolution=(size, size),
                                    max_depth=depth)
        baseline = get_method("pt")
        warm_up(baseline, context)
        scene.sample_pixel_statistics(layout, grid, 0, ("rgb",), spp=1)
        for offsets in (4, 2):
            scene.sample_gradients(layout, grid, 1, 0, offsets=offsets)
        for spp in arguments.spps:
            times = {"pt": [], "base": [], "gradient (4 offsets)": [], "gradient (2 offsets)": []}
            for seed in range(1, arguments.repeats + 1):
                times["pt"].append(run_timed(baseline, context, Budget(spp, seed)).total_seconds)
                times["base"].append(_timed(lambda: scene.sample_pixel_statistics(layout, grid, seed, ("rgb",),
                                                                                  spp=spp)))
                for offsets in (4, 2):
                    times[f"gradient ({offsets} offsets)"].append(
                        _timed(lambda: scene.sample_gradients(layout, grid, spp, seed, offsets=offsets)))
            median = {name: statistics.median(values) for name, values in times.items()}
            pt, base = median["pt"], median["base"]
            print(f"  {scene_name} ({kind}, depth {depth}), spp {spp}: pt {pt:.3f} s, base paths {base:.3f} s "
                  f"({base / pt:.2f}x pt)")
            for offsets in (4, 2):
                total = median[f"gradient ({offsets} offsets)"]
                per_base = (total - base) / base
                verdict = "met" if offsets != 4 or per_base <= OFFSET_TARGET else "NOT met"
                target = f"   target <= {OFFSET_TARGET:g}x: {verdict}" if offsets == 4 else ""
                print(f"    {offsets} offsets: {total:.3f} s = {total / pt:.2f}x pt; offsets cost {per_base:.2f}x the "
                      f"base paths ({(total - pt) / pt:.2f}x pt){target}")


def _reconstruction(arguments):
    rng = np.random.default_rng(0)
    size = 512
    primal = rng.random((size, size, 3))
    gradient_x = 0.1 * rng.standard_normal((size, size - 1, 3))
    gradient_y = 0.1 * rng.standard_normal((size - 1, size, 3))
    screened_poisson(primal, gradient_x, gradient_y)
    l2 = statistics.median(_timed(lambda: screened_poisson(primal, gradient_x, gradient_y))
                           for _ in range(arguments.repeats))
    verdict = "met" if l2 <= L2_TARGET else "NOT met"
    print(f"  screened Poisson L2 at {size}x{size} RGB: {l2:.3f} s   target <= {L2_TARGET:g} s: {verdict}")
    ten = statistics.median(_timed(lambda: screened_poisson_l1(primal, gradient_x, gradient_y, max_iterations=10,
                                                               tolerance=1e-12)) for _ in range(arguments.repeats))
    print(f"  L1 (ADMM) at {size}x{size} RGB: {ten / 10:.3f} s per iteration (10 iterations: {ten:.3f} s)")


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--spp", default="16,64")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--resolution", type=int, default=250)
    arguments = parser.parse_args()
    arguments.spps = [int(value) for value in arguments.spp.split(",")]
    print(f"gradient-domain path tracing at {arguments.resolution}x{arguments.resolution}, medians of "
          f"{arguments.repeats} seeds, 2 cores")
    _sampling(arguments)
    _reconstruction(arguments)


if __name__ == "__main__":
    main()
