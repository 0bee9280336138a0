"""The reference of an equal-time comparison: rendered within its minutes, measured against, and converged.

:class:`ComparisonReference` renders ``compare``'s reference
(:func:`~sparselt.rendering.baseline.cached_reference`: cached 64-spp passes,
optionally on a Dask cluster) within ``--reference-minutes`` of its own
rendering time, and with ``--reference-spp auto`` adds passes until its floor
is at most :data:`AUTO_FLOOR_SHARE` of the smallest debiased headline relMSE
among the cells it judges (:meth:`ComparisonReference.converge`);
:class:`ReferenceMeasure` is the measurement of an image against one
reference, and :func:`remeasure_cells` measures again, from their saved
images, the cells measured against an earlier one.

References
----------
Thesis 8.1.1 (equal-time comparison). The floor's 1/spp law:
:func:`~sparselt.rendering.baseline.reference_spp_for_floor`.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass

import numpy as np

from ..methods import baseline_name
from ..rendering.baseline import reference_spp_for_floor
from .comparison_cells import IMAGES
from .equal_time import fit_baseline, headline_metric, row_floor
from .quality import RELMSE_EPSILON, quality, reference_floor_map

#: ``--reference-spp auto``: start from this many spp, then add passes until the floor is at most
#: :data:`AUTO_FLOOR_SHARE` of the smallest debiased headline relMSE among the cells it judges.
AUTO = "auto"
AUTO_INITIAL_SPP = 1024
AUTO_FLOOR_SHARE = 0.1
#: ``--reference-minutes`` when ``--reference-spp auto`` is given without it.
AUTO_DEFAULT_MINUTES = 10.0
#: At most this many rounds of adding passes and measuring again (each predicts the spp it needs from the 1/spp law).
AUTO_ROUNDS = 4


class ComparisonReference:
    """A comparison's reference: its renders within the minutes it may spend, and its convergence (``auto``).

    Parameters
    ----------
    config : ComparisonConfig
        ``reference_spp`` (a number or :data:`AUTO`), ``reference_minutes``,
        ``reference_seed``, ``kind`` and ``max_depth``.
    setup : SceneSetup
        The comparison's scene (Dask workers load it themselves).
    cache_directory, scheduler : str or None
        As :func:`~sparselt.rendering.baseline.cached_reference`.

    Notes
    -----
    The minutes are the reference's own rendering time: the cells' time
    between its renders is not counted (an auto reference after nine
    minutes of cells once stopped before adding a pass).
    """

    def __init__(self, config, setup, *, cache_directory=None, scheduler=None):
        self.config, self.setup = config, setup
        self.cache_directory, self.scheduler = cache_directory, scheduler
        minutes = config.reference_minutes
        if minutes is None and config.reference_spp == AUTO:
            minutes = AUTO_DEFAULT_MINUTES
        self.minutes = minutes
        self.seconds_left = None if minutes is None else 60.0 * minutes
        self.measure = None

    def start(self, loaded, progress):
        """The first reference: the configured spp, or :data:`AUTO_INITIAL_SPP` for ``auto``."""
        config = self.config
        self.measure = self.render(loaded, AUTO_INITIAL_SPP if config.reference_spp == AUTO else config.reference_spp,
                                   progress)
        return self.measure

    def render(self, loaded, spp, progress):
        """The reference at ``spp`` (its cached passes, the missing ones rendered until its minutes run out) as a
        :class:`ReferenceMeasure` (with the current one's mask); a black one is refused."""
        from ..rendering.baseline import cached_reference

        config = self.config
        started = time.monotonic()
        deadline = None if self.seconds_left is None else started + max(self.seconds_left, 0.0)
        image, record = cached_reference(loaded, config.kind, spp=spp, max_depth=config.max_depth,
                                         seed=config.reference_seed, progress=progress,
                                         cache_directory=self.cache_directory, scheduler=self.scheduler,
                                         setup=self.setup, deadline=deadline, epsilon=RELMSE_EPSILON)
        if self.seconds_left is not None:
            self.seconds_left -= time.monotonic() - started
        if not np.any(image > 0):
            raise ValueError(f"the reference of scene {self.setup.spec.name!r} for kind {config.kind!r} at max depth "
                             f"{config.max_depth} is black (every pixel 0 after {record['spp']} spp): no light "
                             "reaches the camera along the paths this kind counts, so no image can be compared; "
                             "check the scene's emitters, the kind, or raise --max-depth")
        return ReferenceMeasure(image=image, floor_map=reference_floor_map(image, record["variance"]),
                                spp=int(record["spp"]), record=record,
                                mask=None if self.measure is None else self.measure.mask)

    def converge(self, folder, loaded, configuration, progress):
        """``--reference-spp auto``: add passes until the floor is at most :data:`AUTO_FLOOR_SHARE` of the smallest
        debiased headline relMSE among the judged cells, or the minutes run out; every cell measured again
        against each longer reference. Returns ``compare.json``'s ``reference_target``."""
        measured_again = 0
        for _ in range(AUTO_ROUNDS):
            smallest = smallest_judged_error(folder.cells().values(), configuration, self.measure.floor)
            floor = self.measure.floor
            target = None if smallest is None else AUTO_FLOOR_SHARE * smallest
            out_of_time = self.seconds_left is not None and self.seconds_left <= 0
            if floor is None or target is None or floor <= target or out_of_time:
                break
            needed = reference_spp_for_floor(floor, self.measure.spp, target)
            if progress:
                print(f"compare: reference floor {floor:.3g} is above {AUTO_FLOOR_SHARE:g} x the smallest debiased "
                      f"error {smallest:.3g}: adding passes up to {needed} spp", file=sys.stderr)
            longer = self.render(loaded, needed, progress)
            if longer.spp <= self.measure.spp:
                break
            self.measure = longer
            measured_again += remeasure_cells(folder, self.measure)
        smallest = smallest_judged_error(folder.cells().values(), configuration, self.measure.floor)
        floor = self.measure.floor
        target = None if smallest is None else AUTO_FLOOR_SHARE * smallest
        return {"share": AUTO_FLOOR_SHARE, "smallest_debiased_error": smallest, "target_floor": target,
                "floor": floor, "spp": self.measure.spp,
                "met": bool(floor is not None and target is not None and floor <= target),
                "minutes": self.minutes, "cells_measured_again": measured_again}


@dataclass(frozen=True)
class ReferenceMeasure:
    """The reference a comparison measures against, and the measurement of an image against it.

    Attributes
    ----------
    image : ndarray, shape (height, width, 3)
    floor_map : ndarray or None
        The reference's own noise in each pixel's relMSE term
        (:func:`~sparselt.experiments.quality.reference_floor_map`); None for a one-pass reference.
    spp : int
        The samples per pixel it holds (whole passes).
    record : dict
        :func:`~sparselt.rendering.baseline.cached_reference`'s record.
    mask : ndarray of bool or None
        The caustic mask (``relmse_caustic``).
    """

    image: object
    floor_map: object
    spp: int
    record: dict
    mask: object = None

    def __call__(self, image):
        """The quality columns of ``image`` (:func:`~sparselt.experiments.quality.quality`) and ``reference_spp``."""
        return dict(quality(image, self.image, self.mask, self.floor_map), reference_spp=self.spp)

    @property
    def floor(self):
        """The reference's relMSE floor (the mean of its floor map), None when unknown."""
        return None if self.floor_map is None else float(np.mean(self.floor_map))

    def bias_test_variance(self):
        """The per-pixel variance of the reference's mean and its degrees of freedom (passes - 1) for the bias
        test; ``(None, None)``, an exact reference, with one pass."""
        passes, variance = self.record["passes"], self.record["variance"]
        if passes < 2 or not np.all(np.isfinite(variance)):
            return None, None
        return variance, passes - 1

    def summary(self):
        """``compare.json``'s ``reference`` record: the cache key, spp, passes, time, machines and floor."""
        keys = ("key", "spp", "requested_spp", "passes", "seconds", "seconds_this_run", "machines", "cached", "path")
        return dict({key: self.record[key] for key in keys if key in self.record}, relmse_floor=self.floor)


#: Columns of earlier protocols that a measurement against a new reference replaces.
STALE_COLUMNS = ("relmse_debiased", "reference_limited")


def remeasure_cells(folder, measure):
    """Measure again, from their images, the finished cells measured against another reference; their
    records rewritten. Returns how many."""
    count = 0
    for name, cell in folder.cells().items():
        row = cell["row"]
        if row.get("reference_spp") == measure.spp and "relmse_trimmed" in row:
            continue
        image = np.load(folder.path_of(f"{IMAGES}/{name}.npy"))
        row = {key: value for key, value in row.items() if key not in STALE_COLUMNS}
        row.update(measure(image))
        folder.record_cell(name, dict(cell, row=row))
        count += 1
    return count


def smallest_judged_error(cells, configuration, floor):
    """The smallest debiased headline relMSE (mean over seeds) among the cells a comparison judges: every
    row's at the run's budgets (PT's ladder rungs beyond them excluded); None without such cells.

    A cell at or below the reference's noise counts as half the floor (the next round measures it again).
    """
    every = [dict(cell["row"]) for cell in cells]
    rows = [row for row in every if row["spp"] in configuration["spps"]
            and row["method"] in configuration["methods"] + [baseline_name()]]
    if not rows:
        return None
    metric = headline_metric(rows, fit_baseline(every, baseline_name()))
    groups = {}
    for row in rows:
        groups.setdefault((row["method"], row["spp"]), []).append(row[metric] - row_floor(row, metric))
    means = [float(np.mean(values)) for values in groups.values()]
    half = 0.5 * floor if floor else 0.0
    return min(max(value, half) for value in means) if means else None


__all__ = ["AUTO", "AUTO_DEFAULT_MINUTES", "AUTO_FLOOR_SHARE", "AUTO_INITIAL_SPP", "AUTO_ROUNDS", "STALE_COLUMNS",
           "ComparisonReference", "ReferenceMeasure", "remeasure_cells", "smallest_judged_error"]
