"""The contract every comparison method keeps, built-in or plug-in, checked the same way for all.

Two layers, after scikit-learn's ``check_estimator``:

:func:`check_result`
    What the harness checks of every run before it records it: a
    :class:`MethodResult` whose image has the output's shape, dtype float32
    and finite pixels, whose seconds are non-negative, finite and only of
    :data:`TIME_PHASES`, a non-negative integer of path samples and JSON-able
    details. Given the harness's own wall time of the run, time the method did
    not put in a phase is added to ``'other'``: a method cannot make itself
    faster by leaving time untimed.
:func:`check_method`
    What the contract test (``tests/test_method_contract.py``) runs over every
    registered method: :func:`check_result`, phases that add up to the run's
    wall time, the path samples it reports equal to those the renderer drew
    (counted by :class:`SampleCountingScene`), the same image for the same
    seed, and options that survive a JSON round trip.

References
----------
Thesis 8.1.1 (equal time: every second and every sample counted).
scikit-learn's ``utils.estimator_checks`` (one suite over every estimator).
"""

from __future__ import annotations

import dataclasses
import json
import math
import time

import numpy as np

from ..rendering.mitsuba_backend import GRADIENT_SHIFTS, gradient_paths
from .base import TIME_PHASES, MethodResult
from .options import resolve_options

#: Untimed seconds a run may leave outside its phases before :func:`check_method` calls it a breach:
#: the harness's own bookkeeping around ``run`` (result construction, a return) stays well below.
UNTIMED_TOLERANCE_SECONDS = 0.05
UNTIMED_TOLERANCE_FRACTION = 0.1


def check_result(method, result, context, budget, *, wall_seconds=None):
    """Check one run's result; return its seconds per phase (every phase of :data:`TIME_PHASES` present).

    Parameters
    ----------
    method : Method
    result : object
        What ``method.run`` returned.
    context : ComparisonContext
        The run's context (its ``resolution`` is the image's size).
    budget : Budget
    wall_seconds : float, optional
        The harness's wall time of the run; time beyond the phases' sum is
        added to ``'other'``.

    Returns
    -------
    dict
        ``{phase: seconds}`` for every phase.

    Raises
    ------
    ValueError
        The message names the method, the budget and what is wrong.
    """
    where = f"method {method.name!r} at spp {budget.spp}, seed {budget.seed}"
    if not isinstance(result, MethodResult):
        raise ValueError(f"{where} returned {type(result).__name__}, not a sparselt.methods.MethodResult")
    width, height = context.resolution
    image = result.image
    if not isinstance(image, np.ndarray) or image.shape != (height, width, 3):
        shape = getattr(image, "shape", type(image).__name__)
        raise ValueError(f"{where} returned an image of shape {shape}; the comparison needs ({height}, {width}, 3) "
                         "(height, width, RGB)")
    if image.dtype != np.float32:
        raise ValueError(f"{where} returned an image of dtype {image.dtype}; the comparison needs float32")
    if not np.all(np.isfinite(image)):
        raise ValueError(f"{where} produced NaN or infinite pixels")
    if not isinstance(result.seconds, dict):
        raise ValueError(f"{where}: seconds must be a dict of phases ({', '.join(TIME_PHASES)})")
    unknown = sorted(set(result.seconds) - set(TIME_PHASES))
    if unknown:
        raise ValueError(f"{where} reports seconds for {unknown}; the phases are {', '.join(TIME_PHASES)}")
    seconds = {}
    for phase in TIME_PHASES:
        value = result.seconds.get(phase, 0.0)
        if isinstance(value, bool) or not isinstance(value, (int, float, np.floating)) or not math.isfinite(value) \
                or value < 0:
            raise ValueError(f"{where}: seconds[{phase!r}] must be a finite number >= 0, got {value!r}")
        seconds[phase] = float(value)
    samples = result.path_samples
    if isinstance(samples, bool) or not isinstance(samples, (int, np.integer)) or samples < 0:
        raise ValueError(f"{where}: path_samples must be an integer >= 0 (every path sample drawn), got {samples!r}")
    try:
        json.dumps(result.details)
    except (TypeError, ValueError) as error:
        raise ValueError(f"{where}: details must be JSON-able ({error})") from None
    if wall_seconds is not None:
        seconds["other"] += max(0.0, float(wall_seconds) - sum(seconds.values()))
    return seconds


class SampleCountingScene:
    """The renderer adapter with every path sample it draws counted (the contract's witness).

    Wraps a :class:`~sparselt.rendering.mitsuba_backend.MitsubaScene`; each
    sampling entry point adds what it draws to :attr:`path_samples` and
    forwards the call unchanged. The ``aov`` pass draws no path samples; its
    samples go to :attr:`aov_samples`.
    """

    def __init__(self, scene):
        self._scene = scene
        self.path_samples = 0
        self.aov_samples = 0

    def __getattr__(self, name):
        return getattr(self._scene, name)

    def _pixels(self):
        return self._scene.width * self._scene.height

    def sample_cells(self, layout, grid_shape, first_cell, cell_count, spp, seed, *, cells=None):
        count = int(np.size(cells)) if cells is not None else int(cell_count)
        self.path_samples += count * int(spp)
        return self._scene.sample_cells(layout, grid_shape, first_cell, cell_count, spp, seed, cells=cells)

    def sample_pixels(self, layout, grid_shape, spp, seed, first_pixel=0, pixel_count=None, resolution=None,
                      auxiliary=(), lanes=None):
        width, height = resolution or (self._scene.width, self._scene.height)
        count = width * height - first_pixel if pixel_count is None else pixel_count
        self.path_samples += int(count) * int(spp) if lanes is None else int(np.size(lanes[0]))
        return self._scene.sample_pixels(layout, grid_shape, spp, seed, first_pixel=first_pixel,
                                         pixel_count=pixel_count, resolution=resolution, auxiliary=auxiliary,
                                         lanes=lanes)

    def sample_pixel_statistics(self, layout, grid_shape, seed, names, *, spp=None, lanes=None):
        self.path_samples += self._pixels() * int(spp) if lanes is None else int(np.size(lanes[0]))
        return self._scene.sample_pixel_statistics(layout, grid_shape, seed, names, spp=spp, lanes=lanes)

    def sample_gradients(self, layout, grid_shape, spp, seed, *, offsets=4):
        width, height = self._scene.width, self._scene.height
        self.path_samples += int(spp) * gradient_paths(width, height, offsets) if offsets in GRADIENT_SHIFTS else 0
        return self._scene.sample_gradients(layout, grid_shape, spp, seed, offsets=offsets)

    def render_estimator(self, layout, spp, seed):
        self.path_samples += self._pixels() * int(spp)
        return self._scene.render_estimator(layout, spp, seed)

    def render_guided(self, layout, map_shape, tables, densities, spp, seed, *, mode):
        self.path_samples += self._pixels() * int(spp)
        return self._scene.render_guided(layout, map_shape, tables, densities, spp, seed, mode=mode)

    def render_path(self, spp, max_depth, seed=0):
        self.path_samples += self._pixels() * int(spp)
        return self._scene.render_path(spp, max_depth, seed)

    def render_aovs(self, spp, seed=0):
        self.aov_samples += self._pixels() * int(spp)
        return self._scene.render_aovs(spp, seed)


def check_method(method, context, budget):
    """Run ``method`` twice at ``budget`` on ``context`` and check the whole contract.

    ``context.scene`` is wrapped in a :class:`SampleCountingScene` for the
    runs; ``context.options`` should be the method's resolved options.

    Returns
    -------
    dict
        ``result`` (the first :class:`MethodResult`), ``seconds`` (its
        phases, from :func:`check_result`), ``wall_seconds``, ``drawn`` (path
        samples the renderer drew in the first run).

    Raises
    ------
    AssertionError
        A breach of the contract, named.
    """
    options = method.options_of(context)
    record = json.loads(json.dumps(options.record()))
    assert resolve_options(method.Options, record, grid_shape=context.grid_shape, owner=method.name) == options, (
        f"{method.name}: options do not survive a JSON round trip: {record}")
    method.warm_up(context.with_options(options))
    runs = []
    for _ in range(2):
        counting = SampleCountingScene(context.scene)
        start = time.perf_counter()
        result = method.run(dataclasses.replace(context, scene=counting, options=options), budget)
        wall = time.perf_counter() - start
        seconds = check_result(method, result, context, budget)
        runs.append((result, seconds, wall, counting.path_samples))
    (first, seconds, wall, drawn), (second, *_) = runs
    assert first.path_samples == drawn, (
        f"{method.name}: reports {first.path_samples} path samples, the renderer drew {drawn}")
    timed = sum(seconds.values())
    assert timed <= wall * 1.02 + 1e-3, f"{method.name}: phases sum to {timed:.4f} s, more than the run's {wall:.4f} s"
    untimed = wall - timed
    assert untimed <= max(UNTIMED_TOLERANCE_SECONDS, UNTIMED_TOLERANCE_FRACTION * wall), (
        f"{method.name}: {untimed:.4f} s of a {wall:.4f} s run is in no phase")
    assert np.array_equal(first.image, second.image), f"{method.name}: the same seed gave another image"
    return {"result": first, "seconds": seconds, "wall_seconds": wall, "drawn": drawn}


__all__ = ["SampleCountingScene", "check_method", "check_result"]
