"""Overhead of the axis-aligned filters beyond drawing their samples, against PT at the same spp (issue 22).

At 250x250 (dof-sculptures, kind dof, for ``aaf-dof``; courtyard, kind
indirect, for ``aaf-indirect``), kernels warmed first, medians of
``--repeats`` runs with different seeds, in the same run:

- ``pt``: the baseline (Mitsuba's path integrator; the kind's own estimator
  for indirect light);
- ``plain sampling``: the same number of path samples from the sampler
  without auxiliary outputs (what ``samples-mean`` pays);
- the method with every pixel at ``spp`` (``pilot_fraction=1``), by phase.
  Its overhead is its total time minus plain sampling: the per-pixel
  statistics reduced in the sampling kernel, the analysis and the filter.
  Target: at most 10% of PT's time at the same spp;
- the method as it runs by default (a quarter of the budget as pilot, the rest
  allocated per pixel): its total over PT's. The allocation moves samples to
  the pixels the filter cannot help (in focus; near reflectors), whose paths
  are often the longer ones, so its sampling costs more per sample; that is
  part of its equal-time result, not of the filter's overhead;
- the cost of returning every per-sample auxiliary output (depths, normals,
  albedo, secondary-ray length and lobe, lens sample) with the samples.

    .venv/bin/python benchmarks/axis_aligned_overhead.py [--spp 40,163] [--repeats 5]
"""

from __future__ import annotations

import argparse
import statistics
import time

from sparselt.methods import Budget, ComparisonContext, get_method, run_timed, warm_up
from sparselt.methods.pixel_samples import draw_pixel_samples
from sparselt.rendering.layout import path_layout
from sparselt.rendering.mitsuba import AUXILIARY_QUANTITIES, MitsubaScene
from sparselt.rendering.scenes import get_scene

CASES = (("aaf-dof", "dof-sculptures", "dof"), ("aaf-indirect", "courtyard", "indirect"))
TARGET = 0.10


def _available(layout):
    return tuple(name for name in AUXILIARY_QUANTITIES if layout.thin_lens or not name.startswith("lens_"))


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
        scene = MitsubaScene(spec, (size, size))
        layout = path_layout(kind, 3, thin_lens=scene.camera.thin_lens)
        context = ComparisonContext(scene=scene, layout=layout, kind=kind, grid_shape=(size, size, 16, 16),
                                    resolution=(size, size), max_depth=3)
        method, uniform_method, baseline = get_method(name), get_method(name, options={"pilot_fraction": 1.0}), \
            get_method("pt")
        warm_up(method, context)
        warm_up(baseline, context)
        draw_pixel_samples(context, Budget(1, 0))
        for spp in spps:
            # Interleaved per seed, so that a slow spell of the shared machine hits every variant alike.
            pt, plain, uniform, adaptive, auxiliary = [], [], [], [], []
            for seed in range(1, arguments.repeats + 1):
                pt.append(run_timed(baseline, context, Budget(spp, seed)).total_seconds)
                plain.append(_timed(lambda: draw_pixel_samples(context, Budget(spp, seed))))
                auxiliary.append(_timed(lambda: draw_pixel_samples(context, Budget(spp, seed),
                                                                   auxiliary=_available(layout))))
                uniform.append(run_timed(uniform_method, context, Budget(spp, seed)))
                adaptive.append(run_timed(method, context, Budget(spp, seed)).total_seconds)
            pt, plain = statistics.median(pt), statistics.median(plain)
            total = statistics.median(run.total_seconds for run in uniform)
            phases = {phase: statistics.median(run.seconds[phase] for run in uniform) for phase in uniform[0].seconds}
            overhead = total - plain
            verdict = "met" if overhead <= TARGET * pt else "NOT met"
            print(f"  {name} on {scene_name} ({kind}), spp {spp}: pt {pt:.3f} s, plain sampling {plain:.3f} s "
                  f"({plain / pt:.2f}x pt)")
            print(f"    every pixel at spp: {total:.3f} s ({total / pt:.2f}x pt); phases "
                  + ", ".join(f"{phase} {seconds:.3f} s" for phase, seconds in phases.items()))
            print(f"    overhead {overhead:.3f} s = {overhead / pt:.1%} of pt   target <= {TARGET:.0%}: {verdict}")
            print(f"    per-sample auxiliary outputs ({', '.join(_available(layout))}) returned with every sample: "
                  f"{statistics.median(auxiliary):.3f} s, {statistics.median(auxiliary) / plain - 1:+.1%} over plain "
                  "sampling (the methods reduce them in the kernel instead)")
            print(f"    default (pilot + allocation): {statistics.median(adaptive):.3f} s "
                  f"({statistics.median(adaptive) / pt:.2f}x pt)")


if __name__ == "__main__":
    main()
