"""Cost of the CoSaMP pipeline on top of sampling, and of the comparison harness (thesis 8.1, Table 8.1).

1. At the thesis's DoF size (dof-sculptures, 250x250x16x16, spp 40 by default):
   the ``cosamp`` method's phases, kernels warmed first. Its overhead is every
   second that is not sampling (cell means, CoSaMP, synthesis, inverse gamma,
   integration), for the thesis pipeline (``cosamp-thesis``) and the
   cross-fitted one (``cosamp``). Target <= 2.5 s (thesis: CoSaMP alone 14.6 s). The baseline
   measured in the same run is ``pt`` at the same spp: the ratio says how many
   PT images the overhead would have paid for.
2. The harness at the demo's size (issue 20): a ``compare`` run at
   128x128x16x16 (pt, cosamp, bilateral, oidn at 16 and 40 spp, 3 seeds, 3
   timing repeats, PT's automatic ladder; reference cached after its first
   render) and the fraction of its wall time spent outside the methods and
   the reference: scene loading, metrics (SSIM, relMSE, HDR-FLIP), images
   and records written, reports and plots. Target <= 5%.

    .venv/bin/python benchmarks/compare_overhead.py [--spp 40] [--repeats 3] [--harness-only]
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile

from sparselt.experiments.compare import ComparisonConfig, compare
from sparselt.methods import Budget, ComparisonContext, get_method, run_timed, warm_up
from sparselt.rendering.layout import path_layout
from sparselt.rendering.mitsuba import MitsubaScene
from sparselt.rendering.scenes import get_scene


def method_phases(context, name, spp, repeats):
    method = get_method(name, grid_shape=context.grid_shape)
    warm_up(method, context)
    runs = [run_timed(method, context, Budget(spp=spp, seed=seed)) for seed in range(1, repeats + 1)]
    best = min(runs, key=lambda run: run.total_seconds)
    return best


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--spp", type=int, default=40)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--shape", default="250,250,16,16")
    parser.add_argument("--harness-shape", default="128,128,16,16")
    parser.add_argument("--harness-only", action="store_true", help="skip part 1")
    arguments = parser.parse_args()
    shape = tuple(int(v) for v in arguments.shape.split(","))
    if not arguments.harness_only:
        pipeline(arguments, shape)
    harness(tuple(int(v) for v in arguments.harness_shape.split(",")))


def pipeline(arguments, shape):

    scene = MitsubaScene(get_scene("dof-sculptures"), shape[:2])
    context = ComparisonContext(scene=scene, layout=path_layout("dof", 3, thin_lens=True), kind="dof",
                                grid_shape=shape, resolution=shape[:2], max_depth=3)  # default options (gamma 0.25)
    pt = method_phases(context, "pt", arguments.spp, arguments.repeats)
    print(f"dof-sculptures {'x'.join(map(str, shape))}, spp {arguments.spp}, best of {arguments.repeats}, 2 cores")
    print(f"  pt (baseline, same run)        {pt.total_seconds:7.3f} s")
    for name, note in (("cosamp-thesis", "the thesis pipeline: one CoSaMP"),
                       ("cosamp", "cross-fitted: two CoSaMPs on half the samples each")):
        run = method_phases(context, name, arguments.spp, arguments.repeats)
        overhead = run.total_seconds - run.seconds["sampling"]
        print(f"  {name} ({note})")
        print("    phases                       " + ", ".join(f"{k} {v:.3f} s" for k, v in run.seconds.items()))
        print(f"    overhead (not sampling)      {overhead:7.3f} s   target <= 2.5 s: "
              f"{'met' if overhead <= 2.5 else 'NOT met'}   (thesis Table 8.1: CoSaMP 14.6 s)")
        print(f"    overhead / pt time           {overhead / pt.total_seconds:7.2f}x   "
              f"CoSaMP iterations {run.details['cosamp_iterations']}")



def harness(shape):
    with tempfile.TemporaryDirectory() as folder:
        config = ComparisonConfig(scene="dof-sculptures", kind="dof", shape=shape,
                                  methods=("pt", "cosamp", "bilateral", "oidn"), spps=(16, 40), reference_spp=256,
                                  timing_repeats=3)
        compare(config, os.path.join(folder, "warm"), progress=False)  # renders and caches the reference
        result = compare(config, os.path.join(folder, "timed"), progress=False)
        record = json.load(open(os.path.join(folder, "timed", "compare.json")))
    seconds = record["seconds"]
    other = seconds["harness"] - seconds["of_which_scene_load"] - seconds["of_which_reports"] - seconds["of_which_metrics"]
    cells = len(result.rows)
    print(f"harness at {'x'.join(map(str, shape))}, {len(config.methods)} methods, spp {config.spps}, "
          f"{len(config.seeds)} seeds, {config.timing_repeats} repeats, PT ladder {record['pt_ladder']['spps']}: "
          f"{seconds['total']:.2f} s in all, methods {seconds['methods']:.2f} s (warm-ups included), reference "
          f"{seconds['reference']:.2f} s (cached)")
    print(f"  outside them {seconds['harness']:.2f} s = {100 * result.overhead_fraction:.1f}%   target <= 5%: "
          f"{'met' if result.overhead_fraction <= 0.05 else 'NOT met'}")
    print(f"    scene load {seconds['of_which_scene_load']:.2f} s, metrics {seconds['of_which_metrics']:.2f} s "
          f"({cells} cells: SSIM, relMSE, HDR-FLIP), reports and plots {seconds['of_which_reports']:.2f} s, "
          f"images, records and the rest {other:.2f} s")


if __name__ == "__main__":
    main()
