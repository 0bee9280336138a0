"""The renderer as the SFT's oracle: throughput against `sparselt sample`'s, measured in one run (issue 13).

`sample` renders runs of consecutive cells; the oracle renders the scattered
cells an SFT hash asks for (sorted, distinct), in batches of 4M path samples,
with the same random numbers per cell. Both are timed warm, best of 3, on the
same scene and grid; the ratio is oracle samples/s over sample samples/s
(target >= 0.8).

    .venv/bin/python benchmarks/sft_oracle.py [--scene courtyard] [--shape 32,32,4,4,4,4,4,4,4,4] [--spp 1]
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from sparselt.measurement import best_time
from sparselt.recovery.path_space import CellOracle
from sparselt.rendering import mitsuba_backend
from sparselt.rendering.layout import path_layout
from sparselt.rendering.scenes import get_scene


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenes", default="cornell-box,courtyard")
    parser.add_argument("--shape", default="32,32,4,4,4,4,4,4,4,4")
    parser.add_argument("--spp", type=int, default=1)
    parser.add_argument("--fraction", type=float, default=0.05, help="share of the cells read (an SFT reads ~5-30%%)")
    arguments = parser.parse_args()
    shape = tuple(int(v) for v in arguments.shape.split(","))
    size = math.prod(shape)
    count = int(arguments.fraction * size)
    cells = np.sort(np.random.default_rng(1).choice(size, count, replace=False))
    print(f"grid {shape} ({size} cells), {count} cells read, {arguments.spp} spp")
    print(f"{'scene':14s} {'sample Ms/s':>12s} {'oracle Ms/s':>12s} {'ratio':>6s}")
    for name in arguments.scenes.split(","):
        spec = get_scene(name)
        scene = mitsuba_backend.MitsubaScene(spec, shape[:2])
        layout = path_layout("path", 3, thin_lens=scene.camera.thin_lens)
        chunk = max(1, (1 << 22) // arguments.spp)

        def sample_run():
            for first in range(0, count, chunk):
                scene.sample_cells(layout, shape, first, min(chunk, count - first), arguments.spp, 1)

        def oracle_run():
            oracle = CellOracle(lambda c: scene.sample_cells(layout, shape, 0, 0, arguments.spp, 1, cells=c), shape,
                                arguments.spp)
            oracle.read(cells)

        sample_rate = count * arguments.spp / best_time(sample_run, 3)
        oracle_rate = count * arguments.spp / best_time(oracle_run, 3)
        print(f"{name:14s} {sample_rate / 1e6:12.2f} {oracle_rate / 1e6:12.2f} {oracle_rate / sample_rate:6.2f}")


if __name__ == "__main__":
    main()
