"""The renderer as the SFT's oracle: throughput against `sparselt sample`'s, measured in one run (issue 13).

`sample` renders runs of consecutive cells; the oracle renders the scattered
cells an SFT hash asks for (sorted, distinct), in batches of 4M path samples,
with the same random numbers per cell. For the same mix of paths, both cover
the whole image: `sample` renders a full grid of the same kind whose image
plane is reduced so that it has about as many cells as the oracle reads, and
the oracle reads that many random cells of the full-size grid (a new oracle
per repeat, built outside the timing, as one SFT run builds one). Both are
timed warm, best of 3; the ratio is oracle samples/s over sample samples/s
(target >= 0.8).

    .venv/bin/python benchmarks/sft_oracle.py [--scene courtyard] [--shape 32,32,4,4,4,4,4,4,4,4] [--spp 1]
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from sparselt.measurement import best_time
from sparselt.recovery.path_space import CellOracle
from sparselt.rendering.layout import path_layout
from sparselt.rendering.mitsuba import MitsubaScene
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
    side = max(1, round(math.sqrt(count / math.prod(shape[2:]))))
    small = (side, side) + shape[2:]
    print(f"sample: the full grid {small} ({math.prod(small)} cells)")
    for name in arguments.scenes.split(","):
        spec = get_scene(name)
        scene = MitsubaScene(spec, shape[:2])
        small_scene = MitsubaScene(spec, small[:2])
        layout = path_layout("path", 3, thin_lens=scene.camera.thin_lens)
        chunk = max(1, (1 << 22) // arguments.spp)
        small_cells = math.prod(small)

        def sample_run():
            for first in range(0, small_cells, chunk):
                small_scene.sample_cells(layout, small, first, min(chunk, small_cells - first), arguments.spp, 1)

        def evaluate(batch):
            return scene.sample_cells(layout, shape, 0, 0, arguments.spp, 1, cells=batch)

        oracles = [CellOracle(evaluate, shape, arguments.spp) for _ in range(4)]  # warm-up + 3 repeats

        def oracle_run():
            oracles.pop().read(cells)

        sample_rate = small_cells * arguments.spp / best_time(sample_run, 3)
        oracle_rate = count * arguments.spp / best_time(oracle_run, 3)
        print(f"{name:14s} {sample_rate / 1e6:12.2f} {oracle_rate / 1e6:12.2f} {oracle_rate / sample_rate:6.2f}")


if __name__ == "__main__":
    main()
