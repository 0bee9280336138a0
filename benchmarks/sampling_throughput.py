"""PSS sampling throughput against Mitsuba's own path integrator, measured in one run.

For each scene and signal kind, the sampler evaluates ``f(S(u))`` for explicit
primary-sample-space vectors and averages them per cell; the baseline is
``mi.render`` with Mitsuba's ``path`` integrator at the same resolution, depth
and number of samples. Both are timed warm (the first call compiles the
kernels and is discarded), best of ``--repeats``, with ``dr.sync_thread()``
before reading the clock, in ``--rounds`` interleaved rounds. The ratio is
sampler samples/s divided by native samples/s, the median of the rounds
with their range (target >= 1.0, issue 24; a 0.1 s measurement moves by a
few percent from round to round).

    .venv/bin/python benchmarks/sampling_throughput.py [--scenes cornell-box,dof-sculptures]
"""

from __future__ import annotations

import argparse
import math
import os

import numpy as np

from sparselt.measurement import best_time
from sparselt.rendering.layout import path_layout
from sparselt.rendering.mitsuba import MitsubaScene
from sparselt.rendering.scenes import get_scene


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenes", default="cornell-box,dof-sculptures,courtyard")
    parser.add_argument("--resolution", type=int, default=64, help="image width = height")
    parser.add_argument("--spp", type=int, default=256, help="samples per pixel of the native render")
    parser.add_argument("--max-depth", type=int, default=3)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--rounds", type=int, default=3, help="interleaved rounds of native and PSS timings")
    arguments = parser.parse_args()

    width = arguments.resolution
    samples = width * width * arguments.spp
    print(f"{os.cpu_count()} cores; {width}x{width} image, {samples / 1e6:.1f} M samples per measurement, depth {arguments.max_depth}")
    print(f"{'scene':18s} {'kind':14s} {'dims':>4s} {'native Ms/s':>12s} {'PSS Ms/s':>10s} {'ratio':>6s}  rounds")
    for name in arguments.scenes.split(","):
        spec = get_scene(name)
        for kind in ("path", "dof", "indirect"):
            camera_spec = spec.with_lens(0.05, 4.0) if kind == "dof" and not spec.camera.thin_lens else spec
            scene = MitsubaScene(camera_spec, (width, width))
            layout = path_layout(kind, arguments.max_depth, thin_lens=scene.camera.thin_lens)
            extra_axes = len(layout.axes) - 2
            per_axis = max(1, round((arguments.spp / 16) ** (1 / extra_axes))) if extra_axes else 1
            shape = (width, width) + (per_axis,) * extra_axes
            cells = math.prod(shape)
            spp = max(1, samples // cells)
            rounds = []
            for _ in range(arguments.rounds):
                native = best_time(lambda: scene.render_path(arguments.spp, arguments.max_depth, seed=1),
                                   arguments.repeats)
                ours = best_time(lambda: scene.sample_cells(layout, shape, 0, cells, spp, 1), arguments.repeats)
                rounds.append((samples / native, cells * spp / ours))
            native_rate = float(np.median([native for native, _ in rounds]))
            our_rate = float(np.median([ours for _, ours in rounds]))
            ratios = [ours / native for native, ours in rounds]
            print(f"{name:18s} {kind:14s} {len(layout.axes):4d} {native_rate / 1e6:12.2f} {our_rate / 1e6:10.2f} "
                  f"{float(np.median(ratios)):6.2f}  {min(ratios):.2f}-{max(ratios):.2f}")


if __name__ == "__main__":
    main()
