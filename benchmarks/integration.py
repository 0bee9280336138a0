"""Thesis Table 4.1 and Figures 4.1-4.2, measured: time and peak memory of the four integration methods.

A random sparse 4-D Fourier signal (N = s^4, K = N / 10^4) is integrated over
its last two axes (P = s^2 pixels) by 'sum', 'time', 'time-fft' and
'convolution'; each (s, method) runs in a fresh process so its peak memory
(VmHWM over the baseline) includes what ducc0 and numpy allocate. Writes
integration.csv, integration.md, figure_4_1_time.png, figure_4_2_memory.png
and config.json into --out, and prints the table. s = 128 needs about 9 GB
for 'sum' and 'time-fft' (skipped with a reason when that is not available).

    .venv/bin/python benchmarks/integration.py [--sizes 32,48,64,96,128] [--out out/bench-integrate]
"""

from __future__ import annotations

import argparse

from sparselt.experiments.integration_benchmark import DEFAULT_SIZES, run_integration_benchmark
from sparselt.fourier.integration import METHODS


def _integers(text):
    try:
        values = tuple(int(part) for part in text.split(",") if part.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated integers such as 32,64,128, got {text!r}") from None
    if not values:
        raise argparse.ArgumentTypeError("no sizes given")
    return values


def _methods(text):
    methods = tuple(part.strip() for part in text.split(",") if part.strip())
    unknown = [method for method in methods if method not in METHODS]
    if unknown or not methods:
        raise argparse.ArgumentTypeError(f"unknown method(s) {unknown or text!r}; choose from {','.join(METHODS)}")
    return methods


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sizes", type=_integers, default=DEFAULT_SIZES, help="values of s (default: 32,48,64,96,128)")
    parser.add_argument("--methods", type=_methods, default=METHODS, help=f"default: {','.join(METHODS)}")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default: %(default)s)")
    parser.add_argument("--repeats", type=int, default=5, help="timed calls per measurement, best kept (default: %(default)s)")
    parser.add_argument("--out", default="out/bench-integrate", help="output folder (default: %(default)s)")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing output folder's files")
    parser.add_argument("--no-progress", action="store_true", help="no per-measurement lines")
    arguments = parser.parse_args()
    try:
        run_integration_benchmark(arguments.out, sizes=arguments.sizes, methods=arguments.methods, seed=arguments.seed,
                                  repeats=arguments.repeats, overwrite=arguments.overwrite,
                                  progress=not arguments.no_progress)
    except ValueError as error:
        parser.error(str(error))


if __name__ == "__main__":
    main()
