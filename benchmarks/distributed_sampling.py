"""Distributed acquisition on Dask against the in-process run, measured in one run (issue 9).

Three measurements, each a ratio against a baseline measured here:

1. Speed-up of 2 local workers over 1 on a 10-D path signal (target >= 1.7x).
   "1 worker" is reported twice: with its share of the cores (all of them:
   Dr.Jit's pool uses every core) and with one thread (one core, the unit the
   2 workers each get).
2. Overhead of Dask on a small signal against the in-process run (target
   <= 10%): once including the cluster's start, once on a running cluster.
3. Reading: the image of the stored signal in-process (chunk by chunk)
   against ``dask.array`` on the 2-worker cluster.
4. The thesis-scale 10-D signal (100x100x4^8 cells x 64 spp = 4.2e10 path
   samples) on 8 and 64 machines of 2 cores, estimated from the measured
   per-sample cost of the 2-worker run and the measured per-chunk overhead.

Every run writes a real store; kernels are compiled (and the scene's meshes
generated) by a warm-up run first, so no timing includes compilation.

    .venv/bin/python benchmarks/distributed_sampling.py [--scene courtyard] [--shape 16,16,4,4,4,4,4,4,4,4]
"""

from __future__ import annotations

import argparse
import math
import os
import shutil
import tempfile
import time

import dask.array
import numpy as np

from sparselt import load_signal
from sparselt.distributed import WORKER_THREADS_VARIABLE, dask_client
from sparselt.rendering.acquire import AcquisitionConfig, acquire_signal, signal_bytes

THESIS_SAMPLES = 100 * 100 * 4**8 * 64
THESIS_CELLS = 100 * 100 * 4**8


def _seconds(function):
    start = time.perf_counter()
    function()
    return time.perf_counter() - start


def timed(config, folder, **options):
    if os.path.exists(folder):
        shutil.rmtree(folder)
    start = time.perf_counter()
    acquire_signal(config, folder, progress=False, **options)
    return time.perf_counter() - start


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scene", default="courtyard")
    parser.add_argument("--shape", default="16,16,4,4,4,4,4,4,4,4", help="the 10-D path signal measured")
    parser.add_argument("--spp", type=int, default=2)
    parser.add_argument("--small-shape", default="64,64,8,8", help="the small dof signal of the overhead test")
    parser.add_argument("--small-spp", type=int, default=16)
    arguments = parser.parse_args()
    shape = tuple(int(v) for v in arguments.shape.split(","))
    small_shape = tuple(int(v) for v in arguments.small_shape.split(","))
    cores = os.cpu_count()
    big = AcquisitionConfig(scene=arguments.scene, kind="path", shape=shape, spp=arguments.spp, seed=1)
    small = AcquisitionConfig(scene="cornell-box", kind="dof", shape=small_shape, spp=arguments.small_spp, seed=1,
                              aperture=0.1)
    samples = math.prod(shape) * arguments.spp
    folder = tempfile.mkdtemp(prefix="sparselt-distributed-")
    try:
        out = os.path.join(folder, "signal")
        print(f"{cores} cores; {arguments.scene} path signal {shape}, {arguments.spp} spp = {samples / 1e6:.1f} M samples")
        timed(AcquisitionConfig(scene=arguments.scene, kind="path", shape=shape[:2] + (1,) * 8, spp=1), out)  # warm-up
        timed(AcquisitionConfig(scene="cornell-box", kind="dof", shape=(8, 8, 2, 2), spp=1, aperture=0.1), out)

        in_process = timed(big, out)
        with dask_client(workers=1, say=lambda *_: None) as client:
            client.run(lambda: None)
            one_worker = timed(big, out, scheduler=client.scheduler.address)
        # One worker, one thread: what each of the 2 workers gets.
        os.environ[WORKER_THREADS_VARIABLE] = "1"
        try:
            with dask_client(workers=1, say=lambda *_: None) as client:
                one_thread = timed(big, out, scheduler=client.scheduler.address)
        finally:
            del os.environ[WORKER_THREADS_VARIABLE]
        with dask_client(workers=2, say=lambda *_: None) as client:
            two_workers = timed(big, out, scheduler=client.scheduler.address)
        stored = load_signal(out).meta
        chunk_count, chunk_cells = stored["chunk_count"], stored["chunk_cells"]
        print(f"{'run':42s} {'seconds':>8s} {'M samples/s':>12s}")
        for name, seconds in (("in-process (Dr.Jit pool: all cores)", in_process),
                              ("1 Dask worker (its share: all cores)", one_worker),
                              ("1 Dask worker, 1 thread", one_thread),
                              ("2 Dask workers (1 core each)", two_workers)):
            print(f"{name:42s} {seconds:8.2f} {samples / seconds / 1e6:12.2f}")
        print(f"speed-up of 2 workers over 1 worker (its share of the cores): {one_worker / two_workers:.2f}x (target >= 1.7x)")
        print(f"speed-up of 2 workers over 1 worker with 1 thread:            {one_thread / two_workers:.2f}x")
        print(f"2 workers against the in-process run:                        {in_process / two_workers:.2f}x")

        # 2. Overhead on a small signal.
        small_samples = math.prod(small_shape) * arguments.small_spp
        local = min(timed(small, out) for _ in range(3))
        cold = timed(small, out, workers=2)
        with dask_client(workers=2, say=lambda *_: None) as client:
            timed(small, out, scheduler=client.scheduler.address)  # workers build the scene and compile once
            warm = min(timed(small, out, scheduler=client.scheduler.address) for _ in range(3))
        print(f"small signal {small_shape}, {arguments.small_spp} spp ({small_samples / 1e6:.1f} M samples): "
              f"in-process {local:.2f} s, --workers 2 {cold:.2f} s (cluster start included), "
              f"running 2-worker cluster {warm:.2f} s")
        print(f"Dask overhead: {100 * (cold / local - 1):+.0f}% with the cluster's start, "
              f"{100 * (warm / local - 1):+.0f}% on a running cluster (target <= 10%)")

        # 3. Reading a big signal: the image (mean over the non-image axes) in-process, chunk by chunk,
        #    against dask.array on the 2-worker cluster.
        timed(big, out)
        signal = load_signal(out)
        local_image = min(_seconds(signal.image) for _ in range(3))
        with dask_client(workers=2, say=lambda *_: None) as client:
            lazy = dask.array.from_zarr(out, component="data")
            axes = tuple(range(2, lazy.ndim - 1))
            reduce = lambda: lazy.mean(axis=axes, dtype=np.float64).compute()  # noqa: E731
            reduce()
            cluster_image = min(_seconds(reduce) for _ in range(3))
        print(f"image of the {shape} signal ({signal_bytes(shape) / 1e6:.0f} MB): in-process {local_image:.2f} s, "
              f"dask.array on 2 workers {cluster_image:.2f} s ({local_image / cluster_image:.2f}x)")

        # 4. The thesis-scale signal.
        rate = samples / two_workers  # samples/s of one 2-core machine running 2 workers
        per_chunk = two_workers / chunk_count
        thesis_chunks = THESIS_CELLS // ((1 << 22) // 64)
        print(f"measured: {rate / 1e6:.2f} M samples/s per 2-core machine ({arguments.scene}, depth 3), "
              f"{per_chunk * 1e3:.1f} ms per chunk of {chunk_cells} cells ({chunk_count} chunks)")
        for machines in (1, 8, 64):
            hours = THESIS_SAMPLES / (rate * machines) / 3600
            print(f"thesis signal (4.2e10 samples, {thesis_chunks} chunks, 7.9 GB) on {machines:2d} machines of 2 cores: "
                  f"{hours:6.2f} h ({hours * 60:7.1f} min) if the chunks scale like the measured run")
    finally:
        shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    main()
