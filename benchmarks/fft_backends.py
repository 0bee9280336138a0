"""FFT backends on this machine: ducc0 (ours) against scipy.fft and numpy.fft, one run.

Real and complex n-D transforms of the thesis's 4-D signal size (250x250x16x16
= 16M points), float32 and float64, all cores. Prints best-of-``--repeats``
wall time and the ratio to ducc0.
"""

from __future__ import annotations

import argparse
import os

import numpy as np
import scipy.fft

from sparselt.fourier import fft
from sparselt.measurement import best_time


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--shape", default="250,250,16,16")
    parser.add_argument("--repeats", type=int, default=5)
    arguments = parser.parse_args()
    shape = tuple(int(v) for v in arguments.shape.split(","))
    workers = os.cpu_count()
    rng = np.random.default_rng(0)
    print(f"shape {shape} ({np.prod(shape) / 1e6:.1f} M points), {workers} threads")
    print(f"{'transform':28s} {'ducc0 ms':>9s} {'scipy ms':>9s} {'numpy ms':>9s} {'scipy/ducc0':>12s}")
    for dtype in (np.float32, np.float64):
        real = rng.random(shape).astype(dtype)
        complex_ = (real + 1j * real).astype(np.complex64 if dtype == np.float32 else np.complex128)
        cases = [
            ("real forward", lambda: fft.rfftn(real), lambda: scipy.fft.rfftn(real, workers=workers), lambda: np.fft.rfftn(real)),
            ("complex forward", lambda: fft.fftn(complex_), lambda: scipy.fft.fftn(complex_, workers=workers), lambda: np.fft.fftn(complex_)),
        ]
        for name, ours, scipy_version, numpy_version in cases:
            ducc = best_time(ours, arguments.repeats)
            sci = best_time(scipy_version, arguments.repeats)
            num = best_time(numpy_version, max(1, arguments.repeats // 2))
            print(f"{name + ' ' + np.dtype(dtype).name:28s} {ducc * 1e3:9.1f} {sci * 1e3:9.1f} {num * 1e3:9.1f} {sci / ducc:12.2f}")


if __name__ == "__main__":
    main()
