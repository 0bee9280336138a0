"""Table 4.1 and Figures 4.1-4.2, measured: time and peak memory of the four integration methods.

Thesis section 4.3: a random sparse 4-D signal of size ``N = s^4`` with
``K = N / 10^4`` Fourier coefficients (``support = randperm(N, K)``,
``values = rand``) is integrated over its last two dimensions, giving
``P = s^2`` integrals (pixels); ``s`` runs from 32 to 128. Every method of
:func:`~sparselt.fourier.integration.integrate` is timed and its peak memory
measured at each ``s``, and ``log(time)`` and ``log(memory)`` are fitted
against ``log(N)`` to compare with the complexities of Table 4.1.

This module is the ``sparselt bench integrate`` command's entry point,
:func:`run_integration_benchmark`, and its orchestration: it checks the
arguments, records the configuration, and for every ``(s, method)`` either
skips it, measures it in a child process or records the child's failure;
then it has the report written. The parts live in

:mod:`~sparselt.experiments.integration_signal`
    the test signal (:func:`thesis_signal`, drawn by the package's one
    generator :func:`~sparselt.fourier.sparse.random_sparse_fourier`);
:mod:`~sparselt.experiments.integration_child`
    the child process: what it runs, how parent and child talk, how peak
    memory is read;
:mod:`~sparselt.experiments.integration_report`
    the results and the files written into ``out`` (CSV, Markdown table,
    Figures 4.1 and 4.2, ``config.json``).

A size whose signal cannot fit in this machine's memory even with the
lightest requested method (:func:`minimum_bytes`) is refused before anything
runs, naming the largest ``s`` that fits. A method whose estimated peak
(:func:`estimate_peak_bytes`) does not fit in the memory available when its
turn comes is skipped with a recorded reason instead of being run; a child
that dies (killed for memory, say) is recorded as failed. Neither stops the
benchmark. Sizes ``s <= check_max_size`` are checked against
``'convolution'``.

Only coefficients on the integration plane reach the image, and a uniform
draw at ``K = N / 10^4`` puts ``10^-4 s^2`` there on average (0.1 at
``s = 32``): drawn as the thesis says, the methods would be timed integrating
an all-zero image. The signal therefore has at least
``min(minimum_reaching, K, P)`` coefficients on the plane, a documented
deviation from the uniform draw that leaves ``N``, ``K`` and ``P``, and so
every method's cost, unchanged
(:mod:`~sparselt.experiments.integration_signal`). Every measurement records
how many coefficients reach the image and the largest value of the timed
call's image; a size where none reach it is named in a
:class:`RuntimeWarning`, in the report and in
:attr:`IntegrationBenchmarkResult.empty_image_sizes`.

The output is an :class:`~sparselt.storage.folder.ExperimentFolder` whose
identity is the sizes, methods, seed, repeats, density, check size and
``minimum_reaching``: a rerun with the same identity resumes (every measured
``(method, s)`` is a cell and is not measured again), one with another
identity is refused unless ``overwrite``, and a folder holding files
sparselt did not write is refused either way.

References
----------
Thesis chapter 4 (sections 4.1-4.4, Table 4.1, Figures 4.1-4.2).
"""

from __future__ import annotations

import numbers
import os
import sys
import warnings

import numpy as np

from ..checks import check_integer
from ..fourier.integration import METHODS
from ..fourier.sparse import sample_support
from ..measurement import meminfo_bytes
from ..provenance import environment_record
from .integration_child import CHILD_MODULE, CHILD_TIMEOUT_SECONDS, REPEAT_SECONDS, run_child
from .integration_report import (
    CHECK_TOLERANCE,
    CSV_COLUMNS,
    EXPECTED_EXPONENTS,
    MEMORY_FLOOR_BYTES,
    THESIS_ROWS,
    IntegrationBenchmarkResult,
    IntegrationMeasurement,
    empty_image_warning,
    format_bytes,
    format_table,
    measurement_from_record,
    measurement_record,
    progress_line,
    summarise,
    thesis_complexity,
    write_report,
)
from .integration_signal import (
    DIMENSIONS,
    KEEP_AXES,
    MINIMUM_REACHING,
    THESIS_DENSITY,
    coefficient_count,
    contributing_coefficients,
    thesis_signal,
)
from .protocol import Experiment, Unfinished, run_experiment

__all__ = [
    "BYTES_PER_VALUE",
    "CHECK_MAX_SIZE",
    "CHECK_TOLERANCE",
    "CHILD_TIMEOUT_SECONDS",
    "CSV_COLUMNS",
    "DEFAULT_SIZES",
    "DIMENSIONS",
    "EXPECTED_EXPONENTS",
    "INTERPRETER_BYTES",
    "KEEP_AXES",
    "MAXIMUM_SIGNAL_SIZE",
    "MEMORY_FLOOR_BYTES",
    "MINIMUM_REACHING",
    "REPEAT_SECONDS",
    "THESIS_DENSITY",
    "THESIS_ROWS",
    "TIME_BLOCK_VALUES",
    "IntegrationBenchmarkResult",
    "IntegrationMeasurement",
    "coefficient_count",
    "contributing_coefficients",
    "estimate_peak_bytes",
    "format_table",
    "largest_size",
    "minimum_bytes",
    "run_integration_benchmark",
    "sample_support",
    "thesis_complexity",
    "thesis_signal",
]

DEFAULT_SIZES = (32, 48, 64, 96, 128)
CHECK_MAX_SIZE = 48
BYTES_PER_VALUE = np.dtype(np.complex128).itemsize
INTERPRETER_BYTES = 256 * 2**20
#: Largest N = s^4: the support's flat indices are int64.
MAXIMUM_SIGNAL_SIZE = 2**63 - 1
_CHILD_MODULE = CHILD_MODULE  # the module the child runs (a seam the tests replace to simulate a failing child)

# -- the memory guard --------------------------------------------------------


TIME_BLOCK_VALUES = 1 << 20  # basis values per block of the 'time' method (integration.py's default)


def estimate_peak_bytes(method, size, coefficients, *, dimensions=DIMENSIONS):
    """Rough peak memory of ``integrate`` (bytes) for the guard that skips what cannot fit.

    ``sum`` and ``time-fft``: the dense spectrum and the inverse FFT's output,
    ``2 N`` complex128 values. ``time``: the ``(min(K, chunk), P)`` block of
    basis values it evaluates at once. ``convolution``: ``O(K + P)``.
    """
    signal_size = int(size) ** dimensions
    points = int(size) ** len(KEEP_AXES)
    if method in ("sum", "time-fft"):
        return 2 * signal_size * BYTES_PER_VALUE
    if method == "time":
        rows = min(int(coefficients), max(1, TIME_BLOCK_VALUES // points))
        return (rows * points + 2 * rows * int(size) + 2 * points) * BYTES_PER_VALUE + coefficients * dimensions * 8
    return coefficients * (dimensions * 8 + 1) + 3 * points * BYTES_PER_VALUE


def minimum_bytes(size, methods, density):
    """Memory one measurement at ``s = size`` needs at least: the signal (``K`` int64 indices and complex128
    values) plus the lightest of ``methods``' estimated peaks (:func:`estimate_peak_bytes`).

    Returns
    -------
    bytes : int
    method : str
        The lightest method.
    """
    coefficients = coefficient_count(int(size) ** DIMENSIONS, density)
    peaks = {method: estimate_peak_bytes(method, size, coefficients) for method in methods}
    method = min(peaks, key=peaks.get)
    return coefficients * (8 + BYTES_PER_VALUE) + peaks[method] + INTERPRETER_BYTES, method


def largest_size(methods, density, memory_bytes):
    """The largest ``s`` whose :func:`minimum_bytes` fits in ``memory_bytes`` (and N = s^4 in int64); 1 if none."""
    low, high = 1, int(MAXIMUM_SIGNAL_SIZE ** (1 / DIMENSIONS)) + 2
    while high ** DIMENSIONS > MAXIMUM_SIGNAL_SIZE:
        high -= 1
    while low < high:  # the largest s with minimum_bytes(s) <= memory_bytes: bisection (it grows with s)
        middle = (low + high + 1) // 2
        if minimum_bytes(middle, methods, density)[0] <= memory_bytes:
            low = middle
        else:
            high = middle - 1
    return low


def _total_bytes():
    """This machine's memory: ``MemTotal``, or the cgroup's limit where lower (a container); ``None`` where unknown.

    A seam the tests replace to simulate a small machine.
    """
    total = meminfo_bytes("MemTotal")
    try:
        with open("/sys/fs/cgroup/memory.max", encoding="ascii") as handle:
            limit = handle.read().strip()
    except OSError:
        return total
    if limit.isdigit():
        return int(limit) if total is None else min(total, int(limit))
    return total


def _check_sizes_fit(sizes, methods, density):
    """Refuse, before anything runs, a size that cannot fit in this machine's memory with any requested method.

    Raises
    ------
    ValueError
        Naming the size, what it needs, the memory there is and the largest ``s`` that fits.
    """
    total = _total_bytes()
    for size in sizes:
        if total is not None:
            need, method = minimum_bytes(size, methods, density)
            if need > total:
                raise ValueError(
                    f"sizes: s = {size} (N = {size ** DIMENSIONS:.3g}, K = "
                    f"{coefficient_count(size ** DIMENSIONS, density):.3g} coefficients) needs at least "
                    f"{format_bytes(need)} even with the lightest method requested ({method!r}), more than this "
                    f"machine's {format_bytes(total)} of memory; the largest s that fits is "
                    f"{largest_size(methods, density, total)}")
        if size ** DIMENSIONS > MAXIMUM_SIGNAL_SIZE:
            raise ValueError(f"sizes: s = {size} gives N = s^4 = {size ** DIMENSIONS:.3g} values, beyond the int64 "
                             f"indices of the support (at most {MAXIMUM_SIGNAL_SIZE:.3g}); the largest s allowed is "
                             f"{largest_size(methods, density, float('inf'))}")


# -- the parent --------------------------------------------------------------


def _available_bytes():
    """Memory a child measurement may use (a seam the tests replace to simulate a small machine)."""
    return meminfo_bytes("MemAvailable")


def _measure(size, method, *, seed, density, minimum_reaching, repeats, check_max_size):
    """Measure ``method`` at ``s = size`` in a child process, or record why not.

    Parameters
    ----------
    size : int
        ``s``.
    method : str
        The integration method.
    seed, density, minimum_reaching, repeats, check_max_size
        As in :func:`run_integration_benchmark`.

    Returns
    -------
    IntegrationMeasurement
        ``'skipped'`` when :func:`estimate_peak_bytes` does not fit in the
        available memory, ``'failed'`` when the child did not report, else
        ``'measured'`` with notes on an upper-bound peak or a disagreement.
    """
    signal_size = size ** DIMENSIONS
    coefficients = coefficient_count(signal_size, density)
    common = {"method": method, "size": size, "signal_size": signal_size, "coefficients": coefficients,
              "points": size ** len(KEEP_AXES)}
    estimate = estimate_peak_bytes(method, size, coefficients)
    available = _available_bytes()
    if available is not None and estimate + INTERPRETER_BYTES > 0.9 * available:
        return IntegrationMeasurement(**common, status="skipped", estimated_bytes=estimate,
                                      reason=f"needs about {format_bytes(estimate)}, only {format_bytes(available)} available")
    task = {"size": size, "method": method, "seed": seed, "density": density, "minimum_reaching": minimum_reaching,
            "repeats": repeats, "check": size <= check_max_size}
    record, reason = run_child(task, _CHILD_MODULE)
    if record is None:
        return IntegrationMeasurement(**common, status="failed", estimated_bytes=estimate, reason=reason)
    notes = []
    if not record["peak_reset"] and record["peak_bytes"] <= record["preexisting_bytes"]:
        notes.append("peak memory is an upper bound (high-water mark could not be reset and was set before the call)")
    if record["check_error"] is not None and not record["check_error"] <= CHECK_TOLERANCE:
        notes.append(f"disagrees with 'convolution': relative error {record['check_error']:.3g} > {CHECK_TOLERANCE:g}")
    return IntegrationMeasurement(
        **common, status="measured", reason="; ".join(notes), seconds=min(record["seconds"]),
        run_seconds=tuple(record["seconds"]), peak_bytes=record["peak_bytes"], baseline_bytes=record["baseline_bytes"],
        estimated_bytes=estimate, peak_reset=record["peak_reset"],
        contributing_coefficients=record["contributing_coefficients"],
        uniform_contributing_coefficients=record["uniform_contributing_coefficients"], image_max=record["image_max"],
        check_error=record["check_error"])


def _validate(sizes, methods, seed, repeats, density, check_max_size, minimum_reaching):
    """The arguments of :func:`run_integration_benchmark`, checked and normalised (sizes ascending).

    Raises
    ------
    ValueError
        A bad argument; the message names it and what is allowed.
    """
    try:
        sizes = tuple(sizes)
    except TypeError:
        raise ValueError(f"sizes must be a sequence of integers such as (32, 48, 64), got {sizes!r}") from None
    for size in sizes:
        if isinstance(size, bool) or not isinstance(size, (numbers.Integral, np.integer)):
            raise ValueError(f"sizes must be a sequence of integers such as (32, 48, 64), got {size!r} in {sizes!r}")
    sizes = tuple(int(size) for size in sizes)
    if not sizes or any(size < 2 for size in sizes):
        raise ValueError(f"sizes must be a non-empty sequence of integers >= 2, got {sizes}")
    if len(set(sizes)) != len(sizes):
        raise ValueError(f"sizes {sizes} repeat a size")
    if isinstance(methods, str):
        methods = (methods,)
    methods = tuple(methods)
    unknown = [method for method in methods if method not in METHODS]
    if not methods or unknown:
        raise ValueError(f"unknown integration method(s) {unknown or methods!r}; choose from {', '.join(METHODS)}")
    if len(set(methods)) != len(methods):
        raise ValueError(f"methods {methods} repeat a method")
    seed = check_integer("seed", seed, 0)
    repeats = check_integer("repeats", repeats, 1)
    check_max_size = check_integer("check_max_size", check_max_size, 0)
    minimum_reaching = check_integer("minimum_reaching", minimum_reaching, 0)
    try:
        density = float(density)
    except (TypeError, ValueError):
        raise ValueError(f"density (the fraction K / N) must be a number in (0, 1], got {density!r}") from None
    if not 0 < density <= 1:
        raise ValueError(f"density (the fraction K / N) must be in (0, 1], got {density!r}")
    _check_sizes_fit(sizes, methods, density)
    return tuple(sorted(sizes)), methods, int(seed), int(repeats), density, int(check_max_size), minimum_reaching


def run_integration_benchmark(out, *, sizes=DEFAULT_SIZES, methods=METHODS, seed=0, repeats=5,
                              density=THESIS_DENSITY, check_max_size=CHECK_MAX_SIZE,
                              minimum_reaching=MINIMUM_REACHING, overwrite=False, progress=True):
    """Measure Table 4.1 and Figures 4.1-4.2 and write them into folder ``out``.

    Parameters
    ----------
    out : str or path
        Output folder (created); see :mod:`~sparselt.experiments.integration_report`
        for its files.
    sizes : sequence of int, optional
        Values of ``s`` (``N = s^4``); the thesis uses 32 to 128.
    methods : sequence of str, optional
        Integration methods, any of ``'sum'``, ``'time'``, ``'time-fft'``,
        ``'convolution'`` (default all).
    seed : int, optional
        Seed of the random signals (one signal per ``s``, shared by the methods).
    repeats : int, optional
        Timed calls per measurement, best reported; fewer once a measurement's
        calls have taken ``REPEAT_SECONDS``.
    density : float, optional
        ``K / N``; the thesis's ``10^-4`` by default.
    check_max_size : int, optional
        Check every method against ``'convolution'`` at sizes up to this ``s``.
    minimum_reaching : int, optional
        At least ``min(minimum_reaching, K, P)`` coefficients of every signal
        lie on the integration plane and so reach the image
        (:data:`MINIMUM_REACHING` by default); 0 is the thesis's uniform
        draw, whose image is all zero at most sizes (warned about).
    overwrite : bool, optional
        Replace a folder holding another benchmark (another identity); only
        the files sparselt wrote there are removed.
    progress : bool, optional
        Print one line per measurement to standard error and the table to
        standard output.

    Returns
    -------
    IntegrationBenchmarkResult

    Warns
    -----
    RuntimeWarning
        At sizes where no coefficient reaches the image (only possible with
        ``minimum_reaching=0``): the methods were timed integrating zeros.

    Raises
    ------
    ValueError
        A bad argument (a size that cannot fit in memory names the largest
        that does), or ``out`` holding another benchmark without
        ``overwrite`` or files sparselt did not write
        (:class:`~sparselt.storage.folder.FolderError`), before anything runs.
    RuntimeError
        Not on Linux: peak memory is read from ``/proc/self/status``.

    Notes
    -----
    Fitted exponents: least squares of ``log(quantity)`` on ``log(N)`` over the
    measured sizes; for memory only over sizes where the peak exceeds
    ``MEMORY_FLOOR_BYTES`` (below it, page and allocator noise dominate).

    References
    ----------
    Thesis section 4.3 (methodology), Table 4.1, Figures 4.1 and 4.2.
    """
    experiment = IntegrationBenchmark(sizes=sizes, methods=methods, seed=seed, repeats=repeats, density=density,
                                      check_max_size=check_max_size, minimum_reaching=minimum_reaching,
                                      progress=progress)
    result, table = run_experiment(experiment, out, overwrite=overwrite, progress=False)  # its own lines
    if progress:
        print(table)
    warning = empty_image_warning(result)
    if warning is not None:
        warnings.warn(f"integration benchmark: {warning}", RuntimeWarning, stacklevel=2)
    return result


class IntegrationBenchmark(Experiment):
    """``sparselt bench integrate`` as an experiment: one cell per ``(method, s)`` measurement; the report is
    :func:`~sparselt.experiments.integration_report.write_report`'s files.

    A measurement skipped for memory or whose child failed depends on this
    machine's state, not on the identity: it reaches the report but is not
    recorded (:class:`~sparselt.experiments.protocol.Unfinished`), so a rerun
    tries it again. ``config.json`` is written when the folder opens, before
    any measurement. Parameters are those of :func:`run_integration_benchmark`;
    :meth:`validate` checks and normalises them (sizes ascending).
    """

    kind = "bench-integrate"
    cell_unit = "measurement"

    def __init__(self, *, sizes=DEFAULT_SIZES, methods=METHODS, seed=0, repeats=5, density=THESIS_DENSITY,
                 check_max_size=CHECK_MAX_SIZE, minimum_reaching=MINIMUM_REACHING, progress=True):
        self.sizes, self.methods, self.seed, self.repeats = sizes, methods, seed, repeats
        self.density, self.check_max_size, self.minimum_reaching = density, check_max_size, minimum_reaching
        self.progress = progress

    def validate(self):
        (self.sizes, self.methods, self.seed, self.repeats, self.density, self.check_max_size,
         self.minimum_reaching) = _validate(self.sizes, self.methods, self.seed, self.repeats, self.density,
                                            self.check_max_size, self.minimum_reaching)
        if not os.path.exists("/proc/self/status"):
            raise RuntimeError("peak memory is read from /proc/self/status, which this system lacks (Linux only)")

    def identity(self):
        return {"sizes": list(self.sizes), "methods": list(self.methods), "seed": self.seed, "repeats": self.repeats,
                "density": self.density, "check_max_size": self.check_max_size,
                "minimum_reaching": self.minimum_reaching}

    def prepare(self):
        """The resolved configuration (the identity, the constants the report quotes, this machine) and the
        environment, both recorded in ``config.json``."""
        config = dict(self.identity(), **{
            "experiment": "integration-benchmark",
            "thesis": "chapter 4, section 4.3, Table 4.1, Figures 4.1-4.2",
            "repeat_seconds": REPEAT_SECONDS,
            "dimensions": DIMENSIONS,
            "keep_axes": list(KEEP_AXES),
            "dtype": "complex128",
            "values": "uniform in [0, 1)",
            "support": ("uniform without repetition, then at least min(minimum_reaching, K) coefficients moved onto "
                        "the integration plane" if self.minimum_reaching else "uniform without repetition"),
            "time_block_values": TIME_BLOCK_VALUES,
            "check_tolerance": CHECK_TOLERANCE,
            "memory_floor_bytes": MEMORY_FLOOR_BYTES,
            "fft_threads": _fft_threads(),
            "cpu_count": os.cpu_count(),
            "memory_total_bytes": meminfo_bytes("MemTotal"),
        })
        return {"config": config, "environment": environment_record()}

    def begin(self, folder, state):
        folder.write_json("config.json", {"config": state["config"], "environment": state["environment"]})

    def _cells(self):
        """Cell name -> ``(s, method)``, in the order they are measured (sizes ascending, then methods)."""
        return {f"{method}-s{size}": (size, method) for size in self.sizes for method in self.methods}

    def plan(self):
        return list(self._cells())

    def run_cell(self, name, state, folder):
        size, method = self._cells()[name]
        item = _measure(size, method, seed=self.seed, density=self.density, minimum_reaching=self.minimum_reaching,
                        repeats=self.repeats, check_max_size=self.check_max_size)
        record = measurement_record(item)
        return record if item.measured else Unfinished(record)

    def cell_finished(self, name, record, *, resumed):
        if self.progress:
            names = self.plan()
            note = " (measured by an earlier run)" if resumed else ""
            print(f"[{names.index(name) + 1}/{len(names)}] {progress_line(measurement_from_record(record))}{note}",
                  file=sys.stderr, flush=True)

    def report(self, folder, state, records):
        """Every file of :func:`~sparselt.experiments.integration_report.write_report`; returns the result and the
        Markdown table."""
        measurements = tuple(measurement_from_record(records[name]) for name in self.plan())
        return write_report(folder, summarise(measurements, self.sizes, self.methods), state["config"],
                            state["environment"])

    def summary(self, result):
        result, _ = result
        return {"measured": sum(item.measured for item in result.measurements), "cells": len(self.plan())}


def _fft_threads():
    """The number of threads the FFTs use (recorded in the configuration)."""
    from ..fourier import fft

    return fft.default_threads()

