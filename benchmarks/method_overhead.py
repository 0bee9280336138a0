"""Fixed costs of the structure-aware methods over the standard suite's scenes, against PT (issue 37, 1).

For every scene of the built-in ``standard`` suite at ``--scale`` (default
256x256; ``paper`` 1024x576) and every method of ``--methods`` whose kind the
scene has, kernels warmed first and each budget run once untimed, medians of ``--repeats`` runs with different
seeds interleaved per seed (a slow spell of the shared machine hits every
variant alike), in the same run:

- ``pt``: the baseline at the same spp (Mitsuba's path integrator; the kind's
  own estimator for indirect light);
- the method at the same spp, its total and its phases;
- its **overhead**: the method's time beyond what PT takes for the same path
  samples, ``(method - pt(paths)) / pt(paths)``. For the axis-aligned filters
  the path samples are at most PT's at the same spp (the pilot is part of the
  budget; a cost-aware allocation draws fewer samples where paths are long),
  so this is their time beyond PT's at the same spp. A gradient-domain base
  sample is a base path and its offsets (about 5 paths), so its overhead is
  against PT at the same number of paths: the offset paths are its samples,
  not its overhead; the Poisson solve and the estimates are.

Targets (issue 37): at most 15% at 256x256 and at most 10% at 1024x576. The
last lines give, per method, the median and the largest overhead over the
scenes.

    .venv/bin/python benchmarks/method_overhead.py [--scale default] [--spp 16,64] [--repeats 3]
        [--methods aaf-dof,aaf-indirect,gradient-l1,gradient-l2] [--scenes a,b]
"""

from __future__ import annotations

import argparse
import math
import statistics

from sparselt.experiments.standard_suite import applicable_methods, standard_scenes, standard_suite
from sparselt.experiments.suite_config import validate_suite
from sparselt.methods import WARM_UP_SEED, Budget, ComparisonContext, get_method, run_timed, warm_up

TARGETS = {"quick": 0.15, "default": 0.15, "paper": 0.10}
METHODS = ("aaf-dof", "aaf-indirect", "gradient-l1", "gradient-l2")


def _pt_spp_for(result, resolution, spp):
    """PT's spp for the path samples of ``result``: its own spp for a method that samples pixels, more for one
    whose base samples carry offset paths."""
    width, height = resolution
    return max(spp, int(math.ceil(result.path_samples / (width * height))))


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scale", default="default", choices=tuple(TARGETS))
    parser.add_argument("--spp", default="16,64")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--methods", default=",".join(METHODS))
    parser.add_argument("--scenes", default=None, help="only these scenes of the suite, comma separated")
    arguments = parser.parse_args()
    spps = [int(value) for value in arguments.spp.split(",")]
    rows = [row for row in arguments.methods.split(",") if row]
    chosen = arguments.scenes.split(",") if arguments.scenes else [scene.name for scene in standard_scenes()]
    target = TARGETS[arguments.scale]
    print(f"overhead beyond PT for the same path samples, standard suite at {arguments.scale} scale, medians of "
          f"{arguments.repeats} seeds; target <= {target:.0%}")
    overheads = {row: [] for row in rows}
    baseline = get_method("pt")
    for scene in standard_scenes():
        applicable = applicable_methods(rows, scene.kind)
        if scene.name not in chosen or not applicable:
            continue
        config = standard_suite(arguments.scale, methods=applicable, scenes=[scene.name])
        member = config.scenes[0]
        setup = validate_suite(config)[member.name]
        loaded = setup.load(tuple(config.resolution))
        context = ComparisonContext(scene=loaded.scene, layout=loaded.layout, kind=setup.kind,
                                    grid_shape=tuple(setup.grid_shape), resolution=tuple(config.resolution),
                                    max_depth=setup.max_depth)
        methods = [method for method in (get_method(row, grid_shape=context.grid_shape) for row in member.methods)
                   if not method.baseline]
        warm_up(baseline, context)
        for method in methods:
            warm_up(method, context)
        for spp in spps:
            # Each budget once untimed first, as the comparisons do (CellRunner._warm_budget): a budget's first run
            # in a process takes fresh memory, up to 2x the later runs' time.
            run_timed(baseline, context, Budget(spp, WARM_UP_SEED))
            for method in methods:
                pt_spp = _pt_spp_for(run_timed(method, context, Budget(spp, WARM_UP_SEED)), context.resolution, spp)
                if pt_spp != spp:
                    run_timed(baseline, context, Budget(pt_spp, WARM_UP_SEED))
            runs = {method.label: [] for method in methods}
            pt_equal_paths = {method.label: [] for method in methods}
            pt_times = []
            for seed in range(1, arguments.repeats + 1):
                pt_times.append(run_timed(baseline, context, Budget(spp, seed)).total_seconds)
                for method in methods:
                    result = run_timed(method, context, Budget(spp, seed))
                    runs[method.label].append(result)
                    pt_spp = _pt_spp_for(result, context.resolution, spp)
                    pt_equal_paths[method.label].append(
                        pt_times[-1] if pt_spp == spp else
                        run_timed(baseline, context, Budget(pt_spp, seed)).total_seconds)
            pt = statistics.median(pt_times)
            print(f"  {member.name} ({setup.kind}, {context.resolution[0]}x{context.resolution[1]}), spp {spp}: "
                  f"pt {pt:.3f} s")
            for method in methods:
                results = runs[method.label]
                total = statistics.median(run.total_seconds for run in results)
                phases = {phase: statistics.median(run.seconds[phase] for run in results)
                          for phase in results[0].seconds}
                reference = statistics.median(pt_equal_paths[method.label])
                overhead = (total - reference) / reference
                overheads[method.label].append((overhead, f"{member.name} {spp} spp"))
                verdict = "met" if overhead <= target else "NOT met"
                print(f"    {method.label}: {total:.3f} s ({total / pt:.2f}x pt at {spp} spp; pt for its "
                      f"{results[0].path_samples} paths {reference:.3f} s); overhead {overhead:+.1%} "
                      f"[{verdict}]; phases " + ", ".join(f"{phase} {seconds:.3f} s" for phase, seconds in
                                                          phases.items() if seconds > 0))
    print("per method over the scenes and budgets:")
    for row, values in overheads.items():
        if not values:
            continue
        worst = max(values)
        median = statistics.median(value for value, _ in values)
        met = sum(value <= target for value, _ in values)
        print(f"  {row}: median overhead {median:+.1%}, largest {worst[0]:+.1%} ({worst[1]}); target <= "
              f"{target:.0%} met on {met} of {len(values)} (scene, budget) pairs: "
              f"{'met' if met == len(values) else 'NOT met'}")


if __name__ == "__main__":
    main()
