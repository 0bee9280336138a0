"""Where the gradient-domain shift works and where it fails: a map per scene (issue 23).

For each pixel, the variance of one horizontal gradient sample ``f(T u) - f(u)``
(the base path and its offset one pixel to the right, the same random numbers)
over the variance of the difference of two independent samples of the two
pixels. Below 1 the shift correlates the pair (the gradient is cheaper to
estimate than the two pixels); near 1 or above it does not: the offset lands
on other geometry, crosses an emitter's edge, or diverges after a rough bounce.

    PYTHONPATH=src .venv/bin/python examples/gradient_shift_map.py --out docs/experiments/gradient-shift-map

Writes ``shift_map.png`` (image | variance ratio, log scale) per case and
prints, per case, the share of pixels where the shift fails (ratio above 0.5)
and the share of the gradients' total variance those pixels hold.
"""

from __future__ import annotations

import argparse
import pathlib

import numpy as np

from sparselt.images import luminance, srgb_tonemap
from sparselt.rendering.layout import path_layout
from sparselt.rendering.mitsuba import MitsubaScene
from sparselt.rendering.scenes import get_scene
from sparselt.report.plotting import pyplot

CASES = (("cornell-box", "path", 3), ("cornell-box", "path", 5), ("courtyard", "indirect", 3),
         ("cornell-caustics", "path", 5))


def shift_statistics(scene, layout, seeds):
    """Per pixel (all but the last column): paired and independent variances of one +x gradient sample."""
    grid = (scene.width, scene.height) + (2,) * (len(layout.axes) - 2)
    samples = np.array([scene.sample_gradients(layout, grid, 1, seed, offsets=2)[0] for seed in seeds])
    base = luminance(samples[..., 0, :])
    paired = luminance(samples[:, :, :-1, 1] - samples[:, :, :-1, 0]).var(axis=0, ddof=1)
    independent = base[:, :, 1:].var(axis=0, ddof=1) + base[:, :, :-1].var(axis=0, ddof=1)
    return samples[..., 0, :].mean(axis=0), paired, independent


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--resolution", type=int, default=128)
    parser.add_argument("--seeds", type=int, default=64)
    parser.add_argument("--out", type=pathlib.Path, required=True)
    arguments = parser.parse_args()
    arguments.out.mkdir(parents=True, exist_ok=True)
    plt = pyplot()
    figure, axes = plt.subplots(len(CASES), 2, figsize=(7, 3.4 * len(CASES)))
    size = arguments.resolution
    for row, (scene_name, kind, depth) in enumerate(CASES):
        scene = MitsubaScene(get_scene(scene_name), (size, size))
        image, paired, independent = shift_statistics(scene, path_layout(kind, depth), range(arguments.seeds))
        ratio = paired / np.maximum(independent, 1e-12)
        defined = independent > 0
        fails = defined & (ratio > 0.5)
        share = paired[fails].sum() / max(paired[defined].sum(), 1e-30)
        label = f"{scene_name} {kind} depth {depth}"
        print(f"{label}: median ratio {np.median(ratio[defined]):.3f}; the shift fails (ratio > 0.5) at "
              f"{fails.sum() / defined.sum():.1%} of pixels, which hold {share:.1%} of the gradients' variance")
        axes[row, 0].imshow(srgb_tonemap(image))
        axes[row, 0].set_title(label, fontsize=9)
        shown = axes[row, 1].imshow(np.log10(np.where(defined, np.maximum(ratio, 1e-3), np.nan)), vmin=-3, vmax=0.5,
                                    cmap="magma")
        axes[row, 1].set_title(f"log10 var(gradient) / var(independent); fails at {fails.sum() / defined.sum():.0%}",
                               fontsize=8)
        figure.colorbar(shown, ax=axes[row, 1], fraction=0.046)
        for axis in axes[row]:
            axis.set_axis_off()
    figure.tight_layout()
    figure.savefig(arguments.out / "shift_map.png", dpi=110)


if __name__ == "__main__":
    main()
