"""The L1 gradient-domain solve: plain ADMM (the first version) against the defaults (issue 23's L1 part).

In the same run, on a noisy problem like a 16-spp render's (a textured image,
Gaussian noise on the primal and the gradients, 1% outlying gradients), kernels
warmed first, medians of ``--repeats`` runs after a warm-up run, interleaved
so that a slow spell of the shared machine hits both alike:

- ``old``: plain ADMM as gradient-l1 first ran it (primal start, no
  relaxation, float64; :data:`~sparselt.recovery.poisson.PLAIN_ADMM`), 50
  iterations at most, tolerance 1e-3;
- ``new``: :func:`~sparselt.recovery.poisson.screened_poisson_l1`'s defaults
  (L2 start, relaxation 1.6, float32 ``I`` step; Boyd et al. 2011, 3.4.3),
  the same budget.

Printed per size: each one's seconds and iterations, the ratio old / new, and
the objective each reached relative to a long reference run (``--reference``
plain iterations, 1500 by default; Kettunen et al. 2015's L1 objective).

    .venv/bin/python benchmarks/poisson_solve.py [--repeats 5] [--reference 1500] [--large]

``--large`` adds 1024x576 (its reference run alone takes tens of seconds).

Then, per size, ``gradient-l1``'s held-out check
(:func:`~sparselt.recovery.poisson.held_out_l1_check` on two halves of the
problem, 6 ADMM iterations each, and two L2 solves) against one full L1 solve
with the defaults: the check's cost where it keeps the L1 solve (check + solve)
and what it saves where it keeps the L2 image (check + one L2 solve), as
fractions of the full solve.

Last, per size, the held-out choice of alpha
(:func:`~sparselt.recovery.poisson.held_out_alpha`, both gradient methods):
its family of L2 images (8 alphas, one half) in float64 (SciPy's DCTs, the
first version) against float32 (ducc0's, what the choice uses), and the
whole choice on two halves.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from sparselt import kernels
from sparselt.recovery.poisson import (HELD_OUT_ALPHAS, PLAIN_ADMM, forward_differences, held_out_alpha,
                                      held_out_l1_check, l1_objective, screened_poisson, screened_poisson_family,
                                      screened_poisson_l1)

BUDGET = {"max_iterations": 50, "tolerance": 1e-3}  # gradient-l1's defaults


def noisy_problem(height, width, seed=0):
    """A smooth image times a pixel-rate texture, with render-like noise on the primal and the gradients."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:height, 0:width] / max(height, width)
    light = 0.5 + 0.4 * np.sin(6 * x)[..., None] * np.cos(4 * y)[..., None] * np.array([1.0, 0.8, 0.6])
    texture = np.where((np.arange(height)[:, None] // 2 + np.arange(width)[None, :] // 2) % 2, 1.0, 0.5)
    image = light * texture[..., None]
    primal = image + 0.2 * image * rng.standard_normal(image.shape)
    gradients = [g + 0.05 * rng.standard_normal(g.shape) for g in forward_differences(image)]
    outliers = rng.random(gradients[0].shape) < 0.01
    gradients[0][outliers] += 2.0 * rng.standard_normal(int(outliers.sum()))
    return primal, gradients[0], gradients[1]


def _timed(function):
    start = time.perf_counter()
    result = function()
    return time.perf_counter() - start, result


def _medians(steps, repeats):
    """The median seconds of each of ``steps`` (name -> callable), each warmed up once, the repeats interleaved."""
    seconds = {name: [] for name in steps}
    for step in steps.values():
        step()  # warm-up
    for _ in range(repeats):
        for name, step in steps.items():
            seconds[name].append(_timed(step)[0])
    return [statistics.median(seconds[name]) for name in steps]


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--reference", type=int, default=1500)
    parser.add_argument("--large", action="store_true", help="add 1024x576")
    arguments = parser.parse_args()
    sizes = [(128, 128), (256, 256)] + ([(576, 1024)] if arguments.large else [])
    kernels.warm_up()
    configurations = {"old": dict(PLAIN_ADMM, **BUDGET), "new": dict(BUDGET)}
    print(f"L1 screened Poisson (ADMM), budget {BUDGET}, medians of {arguments.repeats} after a warm-up, "
          f"reference: {arguments.reference} plain iterations")
    for height, width in sizes:
        problem = noisy_problem(height, width)
        reference = l1_objective(screened_poisson_l1(*problem, **dict(PLAIN_ADMM, max_iterations=arguments.reference,
                                                                      tolerance=1e-15)).estimate, *problem)
        times = {name: [] for name in configurations}
        results = {}
        for name, options in configurations.items():
            screened_poisson_l1(*problem, **options)  # warm-up
        for _ in range(arguments.repeats):
            for name, options in configurations.items():
                seconds, results[name] = _timed(lambda: screened_poisson_l1(*problem, **options))
                times[name].append(seconds)
        median = {name: statistics.median(values) for name, values in times.items()}
        print(f"  {width}x{height}x3:")
        for name in configurations:
            gap = l1_objective(results[name].estimate, *problem) / reference - 1
            print(f"    {name}: {median[name]:.4f} s (min {min(times[name]):.4f}), {results[name].iterations} "
                  f"iterations ({results[name].stop_reason}), objective {gap:+.2e} relative to the reference")
        print(f"    old / new: {median['old'] / median['new']:.2f}x")
        halves = [noisy_problem(height, width, seed=seed) for seed in (1, 2)]
        steps = {"check": lambda: held_out_l1_check(halves, 0.2),
                 "l1": lambda: screened_poisson_l1(*problem, **BUDGET),
                 "l2": lambda: screened_poisson(*problem, alpha=0.2)}
        check, l1, l2 = _medians(steps, arguments.repeats)
        print(f"    held-out L1 check: {check:.4f} s; L2 solve {l2:.4f} s; where the check keeps L1 it costs "
              f"{(check + l1) / l1:.2f}x the L1 solve alone, where it keeps L2 {(check + l2) / l1:.2f}x")
        steps = {precision: (lambda precision=precision: screened_poisson_family(*halves[0], HELD_OUT_ALPHAS,
                                                                                 precision=precision))
                 for precision in ("double", "single")}
        steps["choice"] = lambda: held_out_alpha(halves)
        double, single, choice = _medians(steps, arguments.repeats)
        print(f"    held-out alpha: family of {len(HELD_OUT_ALPHAS)} L2 images float64 {double:.4f} s, float32 "
              f"{single:.4f} s ({double / single:.2f}x); the whole choice on two halves {choice:.4f} s")


if __name__ == "__main__":
    main()
