"""Energy share of the largest lattice Fourier coefficients of fully sampled 16x16x4^8 path signals (issue 13).

    .venv/bin/python docs/experiments/compressibility-16x16/compressibility.py   # about 2.5 min on 2 cores
"""
import math, time, numpy as np
from sparselt.rendering.acquire import AcquisitionConfig, acquire_signal
from sparselt.recovery.path_space import largest_energy_fraction
shape = (16, 16) + (4,) * 8
N = math.prod(shape)
for scene in ("cornell-box", "courtyard"):
    for spp in (1, 16):
        t = time.perf_counter()
        s = acquire_signal(AcquisitionConfig(scene=scene, kind="path", shape=shape, spp=spp, seed=1), progress=False)
        data = np.asarray(s.data, dtype=np.float64).mean(axis=-1)
        row = {label: largest_energy_fraction(data, max(1, round(f * N))) for label, f in (("K/N", 1e-4), ("10K/N", 1e-3), ("1%", 0.01), ("10%", 0.1))}
        print(scene, spp, {k: f"{v:.1%}" for k, v in row.items()}, f"{time.perf_counter() - t:.0f} s", flush=True)
