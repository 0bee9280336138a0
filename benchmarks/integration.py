"""Thesis Table 4.1 and Figures 4.1-4.2, measured: time and peak memory of the four integration methods.

A random sparse 4-D Fourier signal (N = s^4, K = N / 10^4) is integrated over
its last two axes (P = s^2 pixels) by 'sum', 'time', 'time-fft' and
'convolution'; each (s, method) runs in a fresh process so its peak memory
(VmHWM over the baseline) includes what ducc0 and numpy allocate. Writes
integration.csv, integration.md, figure_4_1_time.png, figure_4_2_memory.png
and config.json into --out, and prints the table. s = 128 needs about 9 GB
for 'sum' and 'time-fft' (skipped with a reason when that is not available).

The same as ``sparselt bench integrate``; its options:

    .venv/bin/python benchmarks/integration.py --out out/bench-integrate [--sizes 32,48,64,96,128]
        [--methods sum,time,time-fft,convolution] [--seed 0] [--repeats 5] [--overwrite]
"""

import sys

from sparselt.cli import main

if __name__ == "__main__":
    sys.exit(main(["bench", "integrate", *sys.argv[1:]]))
