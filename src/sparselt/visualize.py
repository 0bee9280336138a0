"""Pictures of signals: the integrated image and 2-D slices (``sparselt show``)."""

from __future__ import annotations

import numpy as np

from .checks import check_integer
from .experiments.protocol import Experiment, run_experiment
from .images import reference_exposure, srgb_tonemap


def show_signal(signal, out, *, grid=4, client=None, overwrite=False):
    """Write pictures of ``signal`` into folder ``out`` (an :class:`~sparselt.storage.folder.ExperimentFolder`
    whose identity is the signal's content and ``grid``: a rerun rewrites it, another signal is refused
    unless ``overwrite``).

    Files
    -----
    ``image.png``
        The integrated image (mean over the non-image axes), tone-mapped.
    ``slices_x_y.png``
        Image-plane slices at ``grid`` values of the first non-image axis
        pair (other axes at their middle cell): how the image changes with,
        for example, the lens position.
    ``slices_<a>_<b>.png``
        For each consecutive pair of non-image axes ``(a, b)``: the 2-D
        slice over ``(a, b)`` at ``grid x grid`` pixels spread over the image,
        averaged over the remaining axes. This is the per-pixel signal that
        sparse reconstruction works on (thesis figures 5.2, 7.3).

    ``client`` (a ``distributed.Client``) computes the integrated image on a
    Dask cluster (see :meth:`Signal.image`); the slices read single chunks.

    Returns
    -------
    list of str
        The files written.
    """
    check_integer("grid", grid, 1)
    return run_experiment(ShowExperiment(signal, grid=grid, client=client), out, overwrite=overwrite, progress=False)


class ShowExperiment(Experiment):
    """``sparselt show`` as an experiment: no cells; the report is the pictures of the signal."""

    kind = "show"

    def __init__(self, signal, *, grid=4, client=None):
        self.signal, self.grid, self.client = signal, grid, client

    def identity(self):
        from .storage.folder import signal_identity

        return dict(signal_identity(self.signal), grid=self.grid)

    def report(self, folder, state, records):
        return _write_pictures(self.signal, folder, self.grid, self.client)


def _write_pictures(signal, folder, grid, client):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as pyplot

    written = []
    image = signal.image(client=client)
    exposure = reference_exposure(image)
    written.append(folder.write_png("image.png", image, exposure=exposure))

    axes = signal.axes
    extra = list(range(2, len(axes)))
    if not extra:
        return written
    middle = [size // 2 for size in signal.shape]

    # Image-plane slices along the first non-image axis (others at their middle).
    first = extra[0]
    values = np.unique(np.linspace(0, signal.shape[first] - 1, grid).round().astype(int))
    figure, panels = pyplot.subplots(1, len(values), figsize=(3 * len(values), 3.2), squeeze=False)
    for panel, value in zip(panels[0], values):
        index = [slice(None), slice(None)] + [middle[axis] for axis in extra]
        index[first] = value
        picture = np.asarray(signal.data[tuple(index)], dtype=np.float64).transpose(1, 0, 2)
        panel.imshow(srgb_tonemap(picture, exposure), origin="upper")
        panel.set_title(f"{axes[first]} = {value}/{signal.shape[first]}", fontsize=9)
        panel.axis("off")
    figure.suptitle(f"{signal.kind}: image-plane slices (other axes at their middle cell)", fontsize=10)
    written.append(folder.write_figure("slices_x_y.png", figure, dpi=100, bbox_inches="tight"))

    # Per-pixel slices over consecutive pairs of non-image axes.
    width, height = signal.shape[0], signal.shape[1]
    pixels_x = np.linspace(0, width - 1, grid + 2)[1:-1].round().astype(int)
    pixels_y = np.linspace(0, height - 1, grid + 2)[1:-1].round().astype(int)
    for pair_start in range(0, len(extra) - 1, 2):
        a, b = extra[pair_start], extra[pair_start + 1]
        others = tuple(axis - 2 for axis in extra if axis not in (a, b))
        planes = {}
        for y in pixels_y:
            for x in pixels_x:
                cube = np.asarray(signal.data[x, y], dtype=np.float64)  # shape = non-image axes + (3,)
                planes[x, y] = (cube.mean(axis=others) if others else cube).mean(axis=-1)
        # One colour scale for every panel, so that flat and dark pixels look flat and dark.
        top = float(np.percentile(np.concatenate([plane.ravel() for plane in planes.values()]), 99.5)) or 1.0
        figure, panels = pyplot.subplots(len(pixels_y), len(pixels_x), figsize=(2.2 * len(pixels_x), 2.2 * len(pixels_y)), squeeze=False)
        for row, y in enumerate(pixels_y):
            for column, x in enumerate(pixels_x):
                panel = panels[row][column]
                shown = panel.imshow(planes[x, y].T, origin="lower", cmap="inferno", interpolation="nearest", vmin=0.0, vmax=top)
                panel.set_title(f"pixel ({x}, {y})", fontsize=8)
                panel.set_xticks([])
                panel.set_yticks([])
                if row == len(pixels_y) - 1:
                    panel.set_xlabel(axes[a], fontsize=8)
                if column == 0:
                    panel.set_ylabel(axes[b], fontsize=8)
        figure.colorbar(shown, ax=panels, shrink=0.6, label="luminance")
        figure.suptitle(f"{signal.kind}: luminance over ({axes[a]}, {axes[b]}) per pixel", fontsize=10)
        written.append(folder.write_figure(f"slices_{axes[a]}_{axes[b]}.png", figure, dpi=100, bbox_inches="tight"))
    return written
