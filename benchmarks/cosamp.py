"""CoSaMP on the thesis's depth-of-field size: 250x250x16x16 = 16M points, K = N/200 (thesis 8.1).

Cases: exactly K-sparse real signal with 10% and 25% of cells sampled; the
10% case with 1% noise on the samples; a compressible signal (power-law
coefficient magnitudes). float32, all cores, kernels warmed first. For each case prints total time,
iterations, relative error, peak memory (growth of the RSS high-water mark, reset before each
case), the number of FFTs, and total time / (FFTs x one FFT's time measured in
this run): how close recovery comes to its FFT floor.

    .venv/bin/python benchmarks/cosamp.py [--shape 250,250,16,16]
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from sparselt import kernels
from sparselt.fourier import fft
from sparselt.measurement import reset_peak, status_bytes
from sparselt.fourier.sparse import random_sparse_fourier
from sparselt.operators import PartialFourier
from sparselt.recovery.cosamp import cosamp


def random_real_signal(shape, count, rng, decay=None):
    """A real signal with about ``count`` full-spectrum coefficients (conjugate pairs)."""
    return random_sparse_fourier(shape, count, rng, real=True, decay=decay).to_signal().astype(np.float32)


def fft_floor(shape, repeats=5):
    """Seconds of one FFT as CoSaMP runs them: mean of the best real forward and best inverse transform.

    Both as fast as the backend allows: into preallocated outputs, the inverse
    allowed to destroy its input (as :class:`PartialFourier` does).
    """
    grid = np.random.default_rng(0).random(shape, dtype=np.float32)
    spectrum = fft.rfftn(grid)
    scratch = np.empty_like(spectrum)
    output = np.empty_like(grid)
    best_forward = best_inverse = math.inf
    for _ in range(repeats):
        start = time.perf_counter()
        fft.rfftn(grid, out=scratch)
        best_forward = min(best_forward, time.perf_counter() - start)
        scratch[...] = spectrum
        start = time.perf_counter()
        fft.irfftn(scratch, shape[-1], out=output, overwrite_input=True)
        best_inverse = min(best_inverse, time.perf_counter() - start)
    return 0.5 * (best_forward + best_inverse)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--shape", default="250,250,16,16")
    parser.add_argument("--sparsity-ratio", type=float, default=1 / 200)
    parser.add_argument("--seed", type=int, default=0)
    arguments = parser.parse_args()
    shape = tuple(int(v) for v in arguments.shape.split(","))
    size = math.prod(shape)
    count = int(size * arguments.sparsity_ratio)
    rng = np.random.default_rng(arguments.seed)
    kernels.warm_up()  # the numba loops between the FFTs compile (or load from numba's cache) outside the timing
    one_fft = fft_floor(shape)
    print(f"N = {size} ({'x'.join(map(str, shape))}), K = {count}, float32; one FFT = {one_fft * 1e3:.1f} ms")
    print(f"{'case':30s} {'time s':>7s} {'iter':>4s} {'rel. error':>10s} {'peak MB':>8s} {'FFTs':>5s} {'time/FFT floor':>14s}  phases")
    cases = [
        ("exact, 10% sampled", 0.10, 0.0, None),
        ("exact, 25% sampled", 0.25, 0.0, None),
        ("exact + 1% noise, 10% sampled", 0.10, 0.01, None),
        ("compressible (decay 1), 10%", 0.10, 0.0, 1.0),
    ]
    for name, fraction, noise, decay in cases:
        signal = random_real_signal(shape, count, rng, decay)
        indices = np.sort(rng.choice(size, int(fraction * size), replace=False))
        samples = signal.reshape(-1)[indices]
        if noise:
            samples = samples + (noise * np.linalg.norm(samples) / math.sqrt(samples.size)) * rng.standard_normal(samples.size).astype(np.float32)
        reset_peak()
        baseline = status_bytes("VmRSS")
        start = time.perf_counter()
        operator = PartialFourier(shape, indices, real=True, dtype=np.float32)
        result = cosamp(operator, samples, count)
        total = time.perf_counter() - start
        peak = max(0, status_bytes("VmHWM") - baseline)
        error = result.relative_error(signal)
        floor = result.transforms * one_fft
        phases = ", ".join(f"{phase} {seconds:.2f}" for phase, seconds in result.seconds.items())
        print(f"{name:30s} {total:7.2f} {result.iterations:4d} {error:10.2e} {peak / 1e6:8.0f} {result.transforms:5d} "
              f"{total / floor:14.2f}  {phases} ({result.stop_reason})")
        del operator, result, signal, samples


if __name__ == "__main__":
    main()
