"""The cells of an equal-time comparison: each (row, spp, seed) timed in rounds, and PT's automatic ladder.

:class:`CellRunner` runs a comparison's cells for
:class:`~sparselt.experiments.compare.ComparisonExperiment` (its
``run_cells``): every cell ``timing_repeats`` times, in rounds over every
cell, each repeat kept as it finishes
(:meth:`~sparselt.storage.folder.ExperimentFolder.record_repeat`), a cell
recorded with all its repeats; :func:`ladder_search` is the pure search of
PT's rungs, tested on its own.
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass

import numpy as np

from ..methods import TIME_PHASES, WARM_UP_SEED, Budget, collect_recent_garbage, run_timed, warm_up
from ..methods.contract import check_result
from ..methods.variants import variant_file_name
from .equal_time import NOISY_TIMING_RATIO

IMAGES = "images"


def cell_name(method, spp, seed):
    """The file name of a cell: its row (a method name, or a variant written file-safe by
    :func:`~sparselt.methods.variants.variant_file_name`), spp and seed."""
    return f"{variant_file_name(method)}_spp{spp}_seed{seed}"


def ladder_search(run_rung, others, *, smallest_budget, maximum_spp, start=None, rung_error=None,
                  target_error=None):
    """PT's automatic ladder: the rungs (spp) whose times cover every other method's time, and whose errors
    reach every other method's error.

    PT runs at spp = s0, 2 s0, 4 s0, ... (s0 half the smallest budget, at
    least 1) until its time passes every other method's time (and at least
    two rungs ran) and, given ``rung_error``, its error is at most
    ``target_error`` (so that PT's time to a method's quality is read within
    the ladder, not bounded), or the next rung would pass ``maximum_spp``; then at
    s0 / 2, s0 / 4, ... down to 1 spp while its smallest rung is slower than
    the fastest method: nothing is extrapolated at either end
    (:class:`~sparselt.experiments.equal_time.BaselineFit` fits over the
    rungs).

    Parameters
    ----------
    run_rung : callable
        ``run_rung(spp) -> sequence of float``: runs (or reads) PT at
        ``spp`` for every seed and returns its times; its median is the rung's time.
    others : sequence of float
        Every other method's cell times.
    smallest_budget : int
        The comparison's smallest spp.
    maximum_spp : int
        The cap (:attr:`ComparisonConfig.pt_ladder_max_spp`).
    start : sequence of int, optional
        A ladder already run: the search resumes from its last rung.
    rung_error : callable, optional
        ``rung_error(spp) -> float``: PT's mean relMSE at a rung already run.
    target_error : float, optional
        The smallest mean relMSE of every other method's cells.

    Returns
    -------
    dict
        ``spps`` (sorted rungs), ``target_seconds`` (the slowest other
        time), ``reached_seconds`` (the top rung's time), ``capped``,
        ``max_spp``, ``fastest_seconds`` (the fastest other time).
    """
    target = max(others, default=0.0)
    fastest = min(others, default=math.inf)
    steps = list(start or [])
    spp = steps[-1] if steps else max(1, smallest_budget // 2)
    capped = False
    while True:
        reached = float(np.median(run_rung(spp)))
        if spp not in steps:
            steps.append(spp)
        if reached > target and len(steps) >= 2 and (
                rung_error is None or target_error is None or not rung_error(spp) > target_error):
            break
        if 2 * spp > maximum_spp:
            capped = True
            break
        spp *= 2
    # Downwards too, while a method is faster than PT's smallest rung: nothing is extrapolated at either end.
    steps.sort()
    spp = steps[0]
    lowest = float(np.median(run_rung(spp)))
    while spp > 1 and lowest > fastest:
        spp //= 2
        steps.insert(0, spp)
        lowest = float(np.median(run_rung(spp)))  # every rung listed is run (1 spp was once listed unrun)
    return {"spps": steps, "target_seconds": target, "reached_seconds": reached, "capped": capped,
            "max_spp": maximum_spp, "fastest_seconds": fastest}


@dataclass(frozen=True)
class RunOutcome:
    """What :meth:`CellRunner.run_all` measured besides the cells it recorded in the folder.

    Attributes
    ----------
    ladder : dict or None
        PT's ladder (:func:`ladder_search`), None without another method.
    warm_up_seconds : dict
        ``{row: seconds}`` of each row warmed up by this command.
    method_seconds : float
        Wall seconds in the methods (warm-ups and runs).
    metric_seconds : float
        Harness seconds computing the first repeat's metrics.
    """

    ladder: dict | None
    warm_up_seconds: dict
    method_seconds: float
    metric_seconds: float


class CellRunner:
    """Runs a comparison's cells: each (row, spp, seed) ``timing_repeats`` times, in rounds, and PT's ladder.

    A row is a method instance (a method name or a variant, its
    :attr:`~sparselt.methods.base.Method.label`). A repeat re-runs the whole
    method with the same budget (a method gives the same image for the same
    seed, which is checked): re-timing the same computation would leave out
    exactly what varies between runs (the renderer's launches, allocation,
    caches). The time of a cell is the median of its repeats' totals, its
    phases those of the median run, and min and max are recorded.

    The repeats run in **rounds**, not back to back: round 1 runs every
    method's cells once and then PT's ladder (whose extent follows the
    methods' round-1 times); rounds 2, 3, ... run every cell again, PT's
    rungs included, in reverse order on even rounds. A shared machine's speed
    drifts over minutes (two demo runs measured the methods 16-45% slower
    and PT 10-18% slower in the second: PT, timed last, saw another
    machine); in rounds every cell samples the whole run's conditions, and
    the alternating order cancels a linear drift. Each repeat is recorded
    as it finishes (``repeats/NAME.json``), so an interrupted run resumes
    within a round; a cell enters ``cells/`` only with all its repeats.

    Each (row, spp) runs once untimed at the warm-up seed before its first
    timed run in the process (:meth:`_warm_budget`): the method's warm-up
    compiles its kernels at a small budget, this acquires the budget's memory.

    ``rows_so_far`` are the rows of every run of the folder (a rerun's union):
    the ladder covers the cells an earlier run finished too.
    """

    def __init__(self, folder, context, config, measure, exposure, progress, *, rows_so_far):
        self.folder, self.context, self.config = folder, context, config
        self.measure, self.exposure, self.progress = measure, exposure, progress  # image -> quality columns
        self.rows_so_far = tuple(rows_so_far)
        self.seconds = 0.0
        self.warm_up_seconds = {}
        self.warmed_budgets = set()  # (row, spp) run once untimed in this process (_warm_budget)
        self.metric_seconds = 0.0

    # ----------------------------------------------------------------- the plan
    def run_all(self, methods, baseline):
        """Every cell of ``methods`` (the baseline's at the run's budgets and on its ladder).

        Returns
        -------
        RunOutcome
        """
        config = self.config
        budgets = [(spp, seed) for seed in config.seeds for spp in config.spps]
        plan = [(method, spp, seed) for method in methods if method.label != baseline.label
                and method.label in config.methods for spp, seed in budgets]
        if baseline.label in config.methods:
            plan += [(baseline, spp, seed) for spp, seed in budgets]
        for method, spp, seed in plan:  # round 1
            self._repeat(method, spp, seed, 1)
        ladder = None
        if any(method.label != baseline.label for method in methods):
            ladder = self._ladder(lambda spp: [self._repeat(baseline, spp, seed, 1) for seed in config.seeds],
                                  self._other_times(baseline, plan), baseline=baseline)
            plan += [(baseline, spp, seed) for spp in ladder["spps"] for seed in config.seeds
                     if spp not in config.spps or baseline.label not in config.methods]
        for round_number in range(2, config.timing_repeats + 1):
            if self.progress:
                print(f"compare: timing round {round_number} of {config.timing_repeats} ({len(plan)} cells)",
                      file=sys.stderr)
            for method, spp, seed in (reversed(plan) if round_number % 2 == 0 else plan):
                self._repeat(method, spp, seed, round_number)
        for method, spp, seed in plan:
            self._finish(method, spp, seed)
        if ladder is not None:
            # The medians may have moved from round 1's times: extend the ladder (each new rung with all its
            # repeats) until it covers them again.
            ladder = self._ladder(lambda spp: [self._finished(baseline, spp, seed) for seed in config.seeds],
                                  self._other_times(baseline, plan), start=ladder["spps"], baseline=baseline)
        return RunOutcome(ladder=ladder, warm_up_seconds=dict(self.warm_up_seconds), method_seconds=self.seconds,
                          metric_seconds=self.metric_seconds)

    def _ladder(self, run_rung, others, start=None, *, baseline):
        return ladder_search(run_rung, others, smallest_budget=min(self.config.spps),
                             maximum_spp=self.config.pt_ladder_max_spp, start=start,
                             rung_error=lambda spp: self._mean_error(baseline.label, spp),
                             target_error=self._smallest_error(baseline.label))

    def _first_rows(self):
        """Every cell's row as its first repeat measured it (finished cells' rows first)."""
        rows = {name: cell["row"] for name, cell in self.folder.cells().items()}
        for name in self.folder.repeat_names():
            rows.setdefault(name, self.folder.repeats(name)["row"])
        return rows.values()

    def _mean_error(self, row, spp):
        """PT's mean relMSE (untrimmed: it falls with spp on every scene) over the seeds run at ``spp``."""
        values = [entry["relmse"] for entry in self._first_rows() if entry["method"] == row and entry["spp"] == spp]
        return float(np.mean(values)) if values else math.inf

    def _smallest_error(self, baseline):
        """The smallest mean relMSE over seeds among the other rows' cells of this comparison (None without any)."""
        groups = {}
        for entry in self._first_rows():
            if entry["method"] != baseline and entry["method"] in self.rows_so_far:
                groups.setdefault((entry["method"], entry["spp"]), []).append(entry["relmse"])
        return min((float(np.mean(values)) for values in groups.values()), default=None)

    def _other_times(self, baseline, plan):
        """The times of every other row's cell: this run's plan and those an earlier run of the folder
        finished (its union of budgets), which the ladder must cover too."""
        times = {cell_name(method.label, spp, seed): self._time(method.label, spp, seed)
                 for method, spp, seed in plan if method.label != baseline.label}
        for name, done in self.folder.cells().items():
            if done["row"]["method"] != baseline.label and done["row"]["method"] in self.rows_so_far:
                times.setdefault(name, done["row"]["seconds_total"])
        return list(times.values())

    # ----------------------------------------------------------------- one cell
    def _repeats(self, name):
        return self.folder.repeats(name)

    def _time(self, row, spp, seed):
        """The cell's time so far: the median of its repeats (the finished cell's time when it is done)."""
        name = cell_name(row, spp, seed)
        done = self.folder.cell(name)
        if done is not None:
            return done["row"]["seconds_total"]
        return float(np.median(self._repeats(name)["totals"]))

    def _repeat(self, method, spp, seed, round_number):
        """Run repeat ``round_number`` of a cell unless it is done; return the cell's time so far."""
        row = method.label
        name = cell_name(row, spp, seed)
        done = self.folder.cell(name) is not None
        partial = None if done else self._repeats(name)
        if done or (partial is not None and len(partial["totals"]) >= round_number):
            return self._time(row, spp, seed)
        context = self.context
        if row not in self.warm_up_seconds:
            warm_start = time.perf_counter()
            warm_up(method, context)
            self.warm_up_seconds[row] = time.perf_counter() - warm_start
            self.seconds += self.warm_up_seconds[row]
        if (row, spp) not in self.warmed_budgets:
            self._warm_budget(method, spp)
        budget = Budget(spp=spp, seed=seed)
        collect_recent_garbage()  # before the clock starts
        run_start = time.perf_counter()
        result = run_timed(method, context, budget)
        wall = time.perf_counter() - run_start
        self.seconds += wall
        seconds = check_result(method, result, context, budget, wall_seconds=wall)
        if partial is None:
            metrics_start = time.perf_counter()
            cells_row = _row(row, spp, seed, result, seconds, self.measure)
            self.metric_seconds += time.perf_counter() - metrics_start  # harness time, never a method's
            self.folder.write_image(f"{IMAGES}/{name}", result.image, exposure=self.exposure)
            partial = {"row": cells_row, "details": result.details, "phases": [], "totals": [], "wall_seconds": [],
                       "repeat_image_difference": 0.0}
            if self.progress:
                print(f"compare: {row:18s} spp {spp:5d} seed {seed}: {cells_row['seconds_total']:7.3f} s "
                      f"(repeat 1 of {self.config.timing_repeats}), SSIM {cells_row['ssim']:.3f}, relMSE "
                      f"{cells_row['relmse']:.4g}, luminance x{cells_row['luminance_ratio']:.3f}", file=sys.stderr)
        else:
            first = np.load(self.folder.path_of(f"{IMAGES}/{name}.npy"))
            scale = float(np.abs(first).max()) or 1.0
            difference = float(np.abs(result.image.astype(np.float64) - first).max()) / scale
            # Atomic accumulation (the global guided mode splats samples into pixels from many threads) sums in
            # another order each run: equal to float32 rounding, not bitwise. Anything larger is a breach.
            if difference > 1e-4:
                raise ValueError(f"method {row!r} gave another image when run again with the same seed "
                                 f"({seed}) at spp {spp} (largest difference {difference:.2g} of the image's "
                                 "maximum): a method must be a function of its budget")
            partial["repeat_image_difference"] = max(partial["repeat_image_difference"], difference)
        partial["phases"].append(seconds)
        partial["totals"].append(sum(seconds.values()))
        partial["wall_seconds"].append(wall)
        self.folder.record_repeat(name, partial)
        return float(np.median(partial["totals"]))

    def _warm_budget(self, method, spp):
        """Run ``method`` once at ``spp`` untimed (:data:`~sparselt.methods.base.WARM_UP_SEED`, result discarded)
        before its first timed run at that budget.

        A budget's first run in a process is slower than its later ones with no
        kernel compiling (every launch a cache hit in Dr.Jit's kernel history):
        the excess is system time, huge pages faulted in. Our reading: the
        renderer's allocator keeps freed blocks by size, so that run takes
        memory no run of its size has held, which the system zeroes and maps.
        Measured on the 2-core machine: the first 64-spp run of
        ``aaf-indirect`` on courtyard took 2.07 s against 1.30 s for every later
        seed, 1.5 s of it system time; across the workshop scene's suite the
        first repeat of seed 1 was up to 2.3x its second (``aaf-indirect``),
        1.4x for ``gradient-l2``, ``oidn`` and PT's ladder on the indirect kind.
        With two repeats a cell's median is their mean, so seed 1's time carried
        half of it. The method's warm-up (:func:`~sparselt.methods.base.warm_up`,
        a small budget) compiles the kernels; this run acquires the budget's
        memory. Its seconds are added to the row's ``warm_up_seconds``.
        """
        row = method.label
        collect_recent_garbage()  # before the clock starts
        warm_start = time.perf_counter()
        run_timed(method, self.context, Budget(spp=spp, seed=WARM_UP_SEED))
        elapsed = time.perf_counter() - warm_start
        self.warmed_budgets.add((row, spp))
        self.warm_up_seconds[row] = self.warm_up_seconds.get(row, 0.0) + elapsed
        self.seconds += elapsed

    def _finished(self, method, spp, seed):
        """Run a cell's remaining repeats back to back (a rung added after the rounds), finish it; its time."""
        for round_number in range(1, self.config.timing_repeats + 1):
            self._repeat(method, spp, seed, round_number)
        return self._finish(method, spp, seed)

    def _finish(self, method, spp, seed):
        """Record a cell whose repeats are all in: median time, min, max, the median run's phases."""
        name = cell_name(method.label, spp, seed)
        done = self.folder.cell(name)
        if done is not None:
            return done["row"]["seconds_total"]
        partial = self._repeats(name)
        totals = partial["totals"]
        median = sorted(range(len(totals)), key=totals.__getitem__)[len(totals) // 2]
        seconds = partial["phases"][median]
        row = dict(partial["row"], **{f"seconds_{phase}": seconds[phase] for phase in TIME_PHASES})
        row.update(seconds_total=float(np.median(totals)), seconds_total_min=min(totals),
                   seconds_total_max=max(totals), timing_repeats=len(totals),
                   timing_noisy=bool(max(totals) > NOISY_TIMING_RATIO * min(totals)))
        self.folder.record_cell(name, {"row": row, "details": partial["details"], "seconds": seconds,
                                       "repeat_totals": totals,
                                       "repeat_image_difference": partial["repeat_image_difference"],
                                       "options": method.options.record(),
                                       "wall_seconds": partial["wall_seconds"]})
        return row["seconds_total"]


def _row(name, spp, seed, result, seconds, measure):
    row = {"method": name, "spp": spp, "seed": seed, "seconds_total": sum(seconds.values())}
    row.update({f"seconds_{phase}": seconds[phase] for phase in TIME_PHASES})
    row["path_samples"] = int(result.path_samples)
    row.update(measure(result.image))
    return row


__all__ = ["IMAGES", "CellRunner", "RunOutcome", "cell_name", "ladder_search"]
