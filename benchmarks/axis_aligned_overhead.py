"""Overhead of the axis-aligned filters beyond drawing their samples, against PT at the same spp (issue 22).

At 250x250 (dof-sculptures, kind dof, for ``aaf-dof``; courtyard, kind
indirect, for ``aaf-indirect``), kernels warmed first, medians of
``--repeats`` runs with different seeds, in the same run:

- ``pt``: the baseline (Mitsuba's path integrator; the kind's own estimator
  for indirect light);
- ``plain sampling``: the same number of path samples from the sampler
  without auxiliary outputs (what ``samples-mean`` pays);
- the method, by phase. Its overhead is its total time minus plain sampling:
  the auxiliary outputs in the sampling kernel, the pilot pass's bookkeeping
  and allocation, the analysis and the filter. Target: at most 10% of PT's
  time at the same spp.

    .venv/bin/python benchmarks/axis_aligned_overhead.py [--spp 40,163] [--repeats 5]
"""

from __future__ import annotations

import argparse
import statistics
import time

from sparselt.methods import Budget, ComparisonContext, get_method
from sparselt.methods.pixel_samples import draw_pixel_samples
from sparselt.rendering import mitsuba_backend
from sparselt.rendering.layout import path_layout
from sparselt.rendering.scenes import get_scene

CASES = (("aaf-dof", "dof-sculptures", "dof"), ("aaf-indirect", "courtyard", "indirect"))
TARGET = 0.10


def _median_seconds(function, repeats):
    times = []
    for seed in range(1, repeats + 1):
        times.append(function(seed))
    return statistics.median(times)


def _timed(function):
    start = time.perf_counter()
    function()
    return time.perf_counter() - start


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--spp", default="40,163")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--resolution", type=int, default=250)
    arguments = parser.parse_args()
    spps = [int(value) for value in arguments.spp.split(",")]
    size = arguments.resolution
    print(f"axis-aligned filters at {size}x{size}, medians of {arguments.repeats} seeds, 2 cores; target: overhead "
          f"<= {TARGET:.0%} of pt at the same spp")
    for name, scene_name, kind in CASES:
        spec = get_scene(scene_name)
        scene = mitsuba_backend.MitsubaScene(spec, (size, size))
        layout = path_layout(kind, 3, thin_lens=scene.camera.thin_lens)
        context = ComparisonContext(scene=scene, layout=layout, kind=kind, grid_shape=(size, size, 16, 16),
                                    resolution=(size, size), max_depth=3)
        method, baseline = get_method(name), get_method("pt")
        for warm in (method, baseline):
            warm.warm_up(context)
        draw_pixel_samples(context, Budget(1, 0))
        for spp in spps:
            pt = _median_seconds(lambda seed: baseline.run(context, Budget(spp, seed)).total_seconds,
                                 arguments.repeats)
            plain = _median_seconds(lambda seed: _timed(lambda: draw_pixel_samples(context, Budget(spp, seed))),
                                    arguments.repeats)
            runs = [method.run(context, Budget(spp, seed)) for seed in range(1, arguments.repeats + 1)]
            total = statistics.median(run.total_seconds for run in runs)
            phases = {phase: statistics.median(run.seconds[phase] for run in runs) for phase in runs[0].seconds}
            overhead = total - plain
            verdict = "met" if overhead <= TARGET * pt else "NOT met"
            print(f"  {name} on {scene_name} ({kind}), spp {spp}: pt {pt:.3f} s, plain sampling {plain:.3f} s "
                  f"({plain / pt:.2f}x pt), {name} {total:.3f} s ({total / pt:.2f}x pt)")
            print("    phases " + ", ".join(f"{phase} {seconds:.3f} s" for phase, seconds in phases.items()))
            print(f"    overhead {overhead:.3f} s = {overhead / pt:.1%} of pt   target <= {TARGET:.0%}: {verdict}")


if __name__ == "__main__":
    main()
