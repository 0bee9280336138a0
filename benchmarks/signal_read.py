"""The cost of checking every chunk against its CRC-32 on read (issue 18), as a ratio measured in one run.

``Signal.image()`` of a ~200 MB signal (default: dof kind, 256x256x16x16 cells
of the dof-sculptures scene at 1 spp, 201 MB of float32 RGB) three ways,
interleaved, each repeated (median and spread reported), then the read alone
(``np.asarray(Signal.data)``) the same three ways:

* unverified: the image over the raw Zarr array (what ``load_signal`` returned
  before issue 18);
* verified, first read: through ``load_signal``'s verified reader with its
  per-process cache of verified chunks cleared, so every chunk's CRC-32 is
  computed (what a command that reads the signal once pays);
* verified, cached: the same reader again, chunks already verified in this
  process (what a second read costs).

    .venv/bin/python benchmarks/signal_read.py [--signal PATH] [--repeats 5]

Without ``--signal`` the signal is sampled first into a temporary folder
(about 20 s on 2 cores) and removed afterwards.
"""

from __future__ import annotations

import argparse
import os
import platform
import shutil
import statistics
import tempfile
import time

import numpy as np

from sparselt import load_signal
from sparselt.rendering.acquire import AcquisitionConfig, acquire_signal
from sparselt.signal import Signal
from sparselt.storage import zarr_store


def _seconds(function):
    start = time.perf_counter()
    result = function()
    return time.perf_counter() - start, result


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--signal", default=None, help="an existing complete signal store (default: sample one)")
    parser.add_argument("--scene", default="dof-sculptures")
    parser.add_argument("--shape", default="256,256,16,16")
    parser.add_argument("--repeats", type=int, default=5)
    arguments = parser.parse_args()

    folder = None
    path = arguments.signal
    if path is None:
        folder = tempfile.mkdtemp(prefix="sparselt-signal-read-")
        path = os.path.join(folder, "signal")
        shape = tuple(int(size) for size in arguments.shape.split(","))
        config = AcquisitionConfig(scene=arguments.scene, kind="dof", shape=shape, spp=1, seed=1, aperture=0.1)
        seconds, _ = _seconds(lambda: acquire_signal(config, path, progress=False))
        print(f"sampled {arguments.scene} dof {shape} at 1 spp in {seconds:.1f} s")
    try:
        verified = load_signal(path)
        raw = Signal(data=zarr_store.open_data(path), kind=verified.kind, axes=verified.axes, meta=verified.meta,
                     store=verified.store)
        stored = sum(os.path.getsize(os.path.join(root, name)) for root, _, names in os.walk(path) for name in names)
        print(f"{os.cpu_count()} cores, {platform.processor() or platform.machine()}, Python {platform.python_version()}; "
              f"signal {verified.shape} = {verified.data.nbytes / 1e6:.0f} MB of float32 RGB, {stored / 1e6:.0f} MB "
              f"on disk in {verified.meta['chunk_count']} chunks of {tuple(verified.meta['chunk_shape'])}")

        def first_read():
            zarr_store._VERIFIED_CHUNKS.clear()
            return verified.image()

        def first_whole_read():
            zarr_store._VERIFIED_CHUNKS.clear()
            return np.asarray(verified.data)

        measurements = {
            "Signal.image()": {"unverified (raw Zarr array)": raw.image,
                               "verified, first read (CRC-32 computed)": first_read,
                               "verified, cached (chunks already verified)": verified.image},
            "np.asarray(Signal.data), the read alone": {
                "unverified (raw Zarr array)": lambda: np.asarray(raw.data[...]),
                "verified, first read (CRC-32 computed)": first_whole_read,
                "verified, cached (chunks already verified)": lambda: np.asarray(verified.data)},
        }
        for title, runs in measurements.items():
            reference = list(runs.values())[0]()  # warm-up: page cache, imports
            for run in runs.values():
                run()
            times = {name: [] for name in runs}
            for _ in range(arguments.repeats):
                for name, run in runs.items():
                    seconds, result = _seconds(run)
                    assert np.array_equal(result, reference), f"{name}: another result"
                    times[name].append(seconds)
            baseline = statistics.median(times["unverified (raw Zarr array)"])
            print(f"{title}, median of {arguments.repeats} interleaved runs (min .. max):")
            for name, values in times.items():
                median = statistics.median(values)
                print(f"  {name:44s} {median:7.3f} s  ({min(values):.3f} .. {max(values):.3f})  "
                      f"ratio to unverified {median / baseline:.3f}")
    finally:
        if folder is not None:
            shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    main()
