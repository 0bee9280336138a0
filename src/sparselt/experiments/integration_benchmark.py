"""Table 4.1 and Figures 4.1-4.2, measured: time and peak memory of the four integration methods.

Thesis section 4.3: a random sparse 4-D signal of size ``N = s^4`` with
``K = N / 10^4`` Fourier coefficients (``support = randperm(N, K)``,
``values = rand``) is integrated over its last two dimensions, giving
``P = s^2`` integrals (pixels); ``s`` runs from 32 to 128. Every method of
:func:`~sparselt.fourier.integration.integrate` is timed and its peak memory
measured at each ``s``, and ``log(time)`` and ``log(memory)`` are fitted
against ``log(N)`` to compare with the complexities of Table 4.1.

How memory is measured
----------------------
Each ``(s, method)`` runs in a fresh Python process
(``python -m sparselt.experiments.integration_benchmark TASK``), so the peak
is that method's own, including memory that ducc0 and numpy allocate in C.
The child

1. builds the representation in O(K) memory (:func:`sample_support` draws the
   support without ever allocating an ``N``-sized array),
2. runs a tiny warm-up integration with the same method (thread pool, lazy
   imports, FFT plan caches),
3. resets the kernel's high-water mark (``/proc/self/clear_refs``, value 5)
   where the kernel allows it, and reads its resident set size ``VmRSS`` from
   ``/proc/self/status`` as the baseline,
4. runs ``integrate`` once and reports ``VmHWM - baseline`` as the peak, then
   repeats the call for timing (best of the runs),
5. for ``s <= check_max_size`` checks the method against ``'convolution'``.

A method whose estimated peak does not fit in the memory available when its
turn comes is skipped with a recorded reason instead of being run; a child
that dies (killed for memory, say) is recorded as failed. Neither stops the
benchmark.

Files written into ``out``
--------------------------
``integration.csv``
    One row per (method, s): N, K, P, status, best time, every run's time,
    peak memory, baseline, estimate, agreement error, reason.
``integration.md``
    The measured Table 4.1: time and memory per method and ``s``, fitted
    exponents next to Table 4.1's complexities, and ``sum / convolution``
    ratios at the largest ``s``.
``figure_4_1_time.png``, ``figure_4_2_memory.png``
    Time and peak memory against ``N``, log-log, one line per method
    (thesis Figures 4.1 and 4.2).
``config.json``
    The resolved configuration, :func:`~sparselt.provenance.environment_record`
    and the summary results.

References
----------
Thesis chapter 4 (sections 4.1-4.4, Table 4.1, Figures 4.1-4.2).
"""

from __future__ import annotations

import csv
import dataclasses
import gc
import io
import json
import math
import os
import subprocess
import sys
import time
import traceback
from dataclasses import dataclass, field

import numpy as np

from ..checks import check_integer
from ..fourier.integration import METHODS, integrate
from ..fourier.sparse import SparseFourier, random_sparse_fourier, sample_support  # noqa: F401
from ..measurement import meminfo_bytes, reset_peak, status_bytes
from ..provenance import atomic_write_bytes, check_output_folder, environment_record, write_json

DEFAULT_SIZES = (32, 48, 64, 96, 128)
DIMENSIONS = 4
KEEP_AXES = (0, 1)
THESIS_DENSITY = 1e-4
CHECK_MAX_SIZE = 48
CHECK_TOLERANCE = 1e-9
MEMORY_FLOOR_BYTES = 4 * 2**20
REPEAT_SECONDS = 30.0
CHILD_TIMEOUT_SECONDS = 1800
BYTES_PER_VALUE = np.dtype(np.complex128).itemsize
INTERPRETER_BYTES = 256 * 2**20
_CHILD_MODULE = "sparselt.experiments.integration_benchmark"
_RESULT_PREFIX = "INTEGRATION-BENCHMARK-RESULT "

#: Thesis Table 4.1: name, time complexity, memory complexity; then the
#: exponent ``e`` of ``N^e`` they imply with ``K = N / 10^4`` and ``P = N^(1/2)``.
TABLE_4_1 = {
    "sum": ("Sum Integration", "O(N)", "O(N)", "1 (N log N with the inverse FFT)", "1"),
    "time": ("Fourier Time Integration (no FFT)", "O(K P)", "O(K + P)", "1.5", "0.5 to 1"),
    "time-fft": ("Fourier Time Integration (with FFT)", "O(N log N)", "O(N)", "1 (N log N)", "1"),
    "convolution": ("Convolution Integration", "O(P log P)", "O(K + P)", "0.5", "0.5 to 1"),
}


@dataclass(frozen=True)
class IntegrationMeasurement:
    """One ``(s, method)`` measurement.

    ``status`` is ``'measured'``, ``'skipped'`` (estimated memory above what was
    available; ``reason`` says how much) or ``'failed'`` (the child process
    died or raised; ``reason`` says how). ``seconds`` is the best of
    ``run_seconds``; ``peak_bytes`` is ``VmHWM - VmRSS`` around the first
    call; ``check_error`` the largest difference from ``'convolution'``
    relative to the output scale (``None`` when not checked).
    """

    method: str
    size: int
    signal_size: int
    coefficients: int
    points: int
    status: str
    reason: str = ""
    seconds: float | None = None
    run_seconds: tuple = ()
    peak_bytes: int | None = None
    baseline_bytes: int | None = None
    estimated_bytes: int | None = None
    peak_reset: bool | None = None
    contributing_coefficients: int | None = None
    check_error: float | None = None

    @property
    def measured(self):
        return self.status == "measured"


@dataclass(frozen=True)
class IntegrationBenchmarkResult:
    """Everything :func:`run_integration_benchmark` measured and wrote.

    Attributes
    ----------
    measurements : tuple of IntegrationMeasurement
        One per (size, method), sizes ascending.
    time_exponents, memory_exponents : dict
        Method -> fitted exponent ``e`` of ``quantity ~ N^e`` (``None`` when
        fewer than two sizes were measurable).
    fit_sizes : dict
        ``{'time': {method: sizes}, 'memory': {method: sizes}}`` used in the fits.
    ratio_size : int or None
        The largest ``s`` where both ``'sum'`` and ``'convolution'`` were measured.
    speed_ratio, memory_ratio : float or None
        ``sum / convolution`` time and peak memory at ``ratio_size``.
    agreement_passed : bool or None
        Every checked method agreed with ``'convolution'`` within
        ``CHECK_TOLERANCE``; ``None`` when no size was small enough to check.
    files : dict
        Name -> path of every file written.
    """

    measurements: tuple
    time_exponents: dict
    memory_exponents: dict
    fit_sizes: dict
    ratio_size: int | None
    speed_ratio: float | None
    memory_ratio: float | None
    agreement_passed: bool | None
    files: dict = field(default_factory=dict)

    def measurement(self, method, size):
        """The measurement of ``method`` at ``s = size``."""
        for item in self.measurements:
            if item.method == method and item.size == size:
                return item
        raise KeyError(f"no measurement of {method!r} at s={size}")


# -- the thesis signal -------------------------------------------------------


def coefficient_count(signal_size, density=THESIS_DENSITY):
    """``K = floor(N * density)``, at least 1 (the thesis: ``K = N / 10^4``)."""
    return max(1, int(signal_size * density))


def thesis_signal(size, *, density=THESIS_DENSITY, seed=0, dimensions=DIMENSIONS):
    """The random sparse signal of thesis section 4.3, as a :class:`SparseFourier`.

    ``N = size^dimensions``, ``K = coefficient_count(N, density)``, support
    uniformly random without repetition, values uniform in ``[0, 1)`` (stored
    as complex128). The random stream depends on ``(seed, size)`` only, so
    every method at one size sees the same signal.
    """
    shape = (int(size),) * int(dimensions)
    total = math.prod(shape)
    rng = np.random.default_rng([int(seed), int(size)])
    return random_sparse_fourier(shape, coefficient_count(total, density), rng, values="uniform")


def _contributing(representation):
    """Coefficients whose integrated coordinates are all zero (the only ones that reach the image)."""
    coordinates = np.unravel_index(representation.indices, representation.shape)
    on_plane = np.ones(representation.sparsity, dtype=bool)
    for axis in range(len(representation.shape)):
        if axis not in KEEP_AXES:
            on_plane &= coordinates[axis] == 0
    return int(on_plane.sum())


def _check_signal(representation, seed):
    """The measured signal plus coefficients on the kept plane, with complex values.

    At ``K = N / 10^4`` almost no coefficient of the thesis signal has zero
    integrated coordinates, so every method returns (nearly) zeros; adding
    on-plane coefficients makes the agreement check see a non-trivial image.
    """
    shape = representation.shape
    rng = np.random.default_rng([int(seed), shape[0], 1])
    plane = shape[KEEP_AXES[0]] * shape[KEEP_AXES[1]]
    count = min(plane, max(8, representation.sparsity))
    kept = np.unravel_index(rng.choice(plane, size=count, replace=False), (shape[KEEP_AXES[0]], shape[KEEP_AXES[1]]))
    coordinates = [np.zeros(count, dtype=np.int64) for _ in shape]
    coordinates[KEEP_AXES[0]], coordinates[KEEP_AXES[1]] = kept
    support = np.union1d(representation.indices, np.ravel_multi_index(tuple(coordinates), shape))
    values = rng.random(support.size) + 1j * rng.random(support.size)
    return SparseFourier(shape, support, values)


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


# -- the child process -------------------------------------------------------


def _measure_here(task):
    """Run one measurement in this process (the child); returns a JSON-able dict."""
    size, method, seed = int(task["size"]), task["method"], int(task["seed"])
    density, repeats = float(task["density"]), int(task["repeats"])
    integrate(thesis_signal(4, density=0.05, seed=seed), KEEP_AXES, method)  # warm-up
    representation = thesis_signal(size, density=density, seed=seed)
    gc.collect()
    reset = reset_peak()
    baseline = status_bytes("VmRSS")
    preexisting = status_bytes("VmHWM") - baseline
    start = time.perf_counter()
    result = integrate(representation, KEEP_AXES, method)
    seconds = [time.perf_counter() - start]
    peak = status_bytes("VmHWM") - baseline
    while len(seconds) < repeats and sum(seconds) < REPEAT_SECONDS:
        start = time.perf_counter()
        integrate(representation, KEEP_AXES, method)
        seconds.append(time.perf_counter() - start)
    check_error = None
    if task["check"]:
        # The measured signal against 'convolution', relative to one coefficient's contribution max|c| / N ...
        reference = integrate(representation, KEEP_AXES, "convolution")
        scale = float(np.abs(representation.values).max()) / representation.size
        measured_error = float(np.abs(result - reference).max()) / scale
        # ... and a signal with on-plane coefficients, relative to its largest output.
        checked = _check_signal(representation, seed)
        reference = integrate(checked, KEEP_AXES, "convolution")
        check_error = max(measured_error, float(np.abs(integrate(checked, KEEP_AXES, method) - reference).max())
                          / float(np.abs(reference).max()))
    return {
        "seconds": seconds,
        "peak_bytes": int(peak),
        "baseline_bytes": int(baseline),
        "preexisting_bytes": int(preexisting),
        "peak_reset": reset,
        "contributing_coefficients": _contributing(representation),
        "check_error": check_error,
        "output_shape": list(result.shape),
    }


def _child_main(arguments):
    try:
        record = _measure_here(json.loads(arguments[0]))
    except Exception:  # report any failure to the parent, which records it
        traceback.print_exc()
        return 1
    sys.stdout.write(_RESULT_PREFIX + json.dumps(record) + "\n")
    sys.stdout.flush()
    return 0


# -- the parent --------------------------------------------------------------


def _available_bytes():
    """Memory a child measurement may use (a seam the tests replace to simulate a small machine)."""
    return meminfo_bytes("MemAvailable")


def _child_environment():
    environment = dict(os.environ)
    source = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    environment["PYTHONPATH"] = os.pathsep.join(filter(None, [source, environment.get("PYTHONPATH")]))
    return environment


def _run_child(task):
    """Measure in a fresh process; returns ``(record, None)`` or ``(None, reason)``."""
    command = [sys.executable, "-m", _CHILD_MODULE, json.dumps(task)]
    try:
        completed = subprocess.run(command, capture_output=True, text=True, timeout=CHILD_TIMEOUT_SECONDS,
                                   env=_child_environment())
    except subprocess.TimeoutExpired:
        return None, f"timed out after {CHILD_TIMEOUT_SECONDS} s"
    for line in completed.stdout.splitlines():
        if line.startswith(_RESULT_PREFIX) and completed.returncode == 0:
            return json.loads(line[len(_RESULT_PREFIX):]), None
    if completed.returncode < 0:
        signal_number = -completed.returncode
        hint = " (killed: out of memory?)" if signal_number == 9 else ""
        return None, f"child process ended by signal {signal_number}{hint}"
    lines = [line for line in completed.stderr.strip().splitlines() if line.strip()]
    return None, f"child process failed (exit {completed.returncode}): {lines[-1] if lines else 'no message'}"


def _measure(size, method, *, seed, density, repeats, check_max_size):
    signal_size = size ** DIMENSIONS
    coefficients = coefficient_count(signal_size, density)
    common = {"method": method, "size": size, "signal_size": signal_size, "coefficients": coefficients,
              "points": size ** len(KEEP_AXES)}
    estimate = estimate_peak_bytes(method, size, coefficients)
    available = _available_bytes()
    if available is not None and estimate + INTERPRETER_BYTES > 0.9 * available:
        return IntegrationMeasurement(**common, status="skipped", estimated_bytes=estimate,
                                      reason=f"needs about {_format_bytes(estimate)}, only {_format_bytes(available)} available")
    task = {"size": size, "method": method, "seed": seed, "density": density, "repeats": repeats,
            "check": size <= check_max_size}
    record, reason = _run_child(task)
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
        contributing_coefficients=record["contributing_coefficients"], check_error=record["check_error"])


def _validate(sizes, methods, seed, repeats, density, check_max_size):
    try:
        sizes = tuple(int(size) for size in sizes)
    except (TypeError, ValueError):
        raise ValueError(f"sizes must be a sequence of integers such as (32, 48, 64), got {sizes!r}") from None
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
    if not 0 < float(density) <= 1:
        raise ValueError(f"density (the fraction K / N) must be in (0, 1], got {density!r}")
    return tuple(sorted(sizes)), methods, int(seed), int(repeats), float(density), int(check_max_size)


def run_integration_benchmark(out, *, sizes=DEFAULT_SIZES, methods=METHODS, seed=0, repeats=5,
                              density=THESIS_DENSITY, check_max_size=CHECK_MAX_SIZE, overwrite=False, progress=True):
    """Measure Table 4.1 and Figures 4.1-4.2 and write them into folder ``out``.

    Parameters
    ----------
    out : str or path
        Output folder (created); see the module docstring for its files.
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
    overwrite : bool, optional
        Allow writing into a non-empty ``out``.
    progress : bool, optional
        Print one line per measurement to standard error and the table to
        standard output.

    Returns
    -------
    IntegrationBenchmarkResult

    Raises
    ------
    ValueError
        A bad argument, or ``out`` not empty without ``overwrite``.
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
    sizes, methods, seed, repeats, density, check_max_size = _validate(sizes, methods, seed, repeats, density, check_max_size)
    if not os.path.exists("/proc/self/status"):
        raise RuntimeError("peak memory is read from /proc/self/status, which this system lacks (Linux only)")
    out = os.fspath(out)
    check_output_folder(out, overwrite=overwrite)
    os.makedirs(out, exist_ok=True)
    config = {
        "experiment": "integration-benchmark",
        "thesis": "chapter 4, section 4.3, Table 4.1, Figures 4.1-4.2",
        "sizes": list(sizes),
        "methods": list(methods),
        "seed": seed,
        "repeats": repeats,
        "repeat_seconds": REPEAT_SECONDS,
        "density": density,
        "dimensions": DIMENSIONS,
        "keep_axes": list(KEEP_AXES),
        "dtype": "complex128",
        "values": "uniform in [0, 1)",
        "time_block_values": TIME_BLOCK_VALUES,
        "check_max_size": check_max_size,
        "check_tolerance": CHECK_TOLERANCE,
        "memory_floor_bytes": MEMORY_FLOOR_BYTES,
        "fft_threads": _fft_threads(),
        "cpu_count": os.cpu_count(),
        "memory_total_bytes": meminfo_bytes("MemTotal"),
    }
    environment = environment_record()
    write_json(os.path.join(out, "config.json"), {"config": config, "environment": environment})

    measurements = []
    total = len(sizes) * len(methods)
    for size in sizes:
        for method in methods:
            item = _measure(size, method, seed=seed, density=density, repeats=repeats, check_max_size=check_max_size)
            measurements.append(item)
            if progress:
                print(f"[{len(measurements)}/{total}] {_progress_line(item)}", file=sys.stderr, flush=True)

    result = _summarise(tuple(measurements), sizes, methods)
    files = {name: os.path.join(out, name) for name in
             ("integration.csv", "integration.md", "figure_4_1_time.png", "figure_4_2_memory.png", "config.json")}
    table = format_table(result, config)
    atomic_write_bytes(files["integration.csv"], _csv_text(result.measurements).encode())
    atomic_write_bytes(files["integration.md"], table.encode())
    _plot(result.measurements, methods, "time", files["figure_4_1_time.png"])
    _plot(result.measurements, methods, "memory", files["figure_4_2_memory.png"])
    write_json(files["config.json"], {"config": config, "environment": environment, "results": _summary_record(result)})
    result = dataclasses.replace(result, files=files)
    if progress:
        print(table)
    return result


def _progress_line(item):
    head = f"s={item.size:<4d} N={item.signal_size:<10.3g} {item.method:<12s}"
    if not item.measured:
        return f"{head} {item.status}: {item.reason}"
    check = "" if item.check_error is None else f", agreement error {item.check_error:.2g}"
    return (f"{head} {_format_seconds(item.seconds)} (best of {len(item.run_seconds)}), "
            f"peak {_format_bytes(item.peak_bytes)}{check}")


def _fft_threads():
    from ..fourier import fft

    return fft.default_threads()


def _fit_exponent(points):
    if len(points) < 2:
        return None
    sizes, values = zip(*points)
    return float(np.polyfit(np.log(sizes), np.log(values), 1)[0])


def _summarise(measurements, sizes, methods):
    time_exponents, memory_exponents = {}, {}
    fit_sizes = {"time": {}, "memory": {}}
    for method in methods:
        rows = [item for item in measurements if item.method == method and item.measured]
        timed = [item for item in rows if item.seconds and item.seconds > 0]
        heavy = [item for item in rows if item.peak_bytes is not None and item.peak_bytes > MEMORY_FLOOR_BYTES]
        time_exponents[method] = _fit_exponent([(item.signal_size, item.seconds) for item in timed])
        memory_exponents[method] = _fit_exponent([(item.signal_size, item.peak_bytes) for item in heavy])
        fit_sizes["time"][method] = [item.size for item in timed]
        fit_sizes["memory"][method] = [item.size for item in heavy]
    ratio_size = speed_ratio = memory_ratio = None
    for size in sorted(sizes, reverse=True):
        pair = {item.method: item for item in measurements if item.size == size and item.measured}
        if "sum" in pair and "convolution" in pair:
            ratio_size = size
            speed_ratio = pair["sum"].seconds / pair["convolution"].seconds
            if pair["convolution"].peak_bytes > 0:
                memory_ratio = pair["sum"].peak_bytes / pair["convolution"].peak_bytes
            break
    checked = [item for item in measurements if item.check_error is not None]
    agreement = all(item.check_error <= CHECK_TOLERANCE for item in checked) if checked else None
    return IntegrationBenchmarkResult(measurements, time_exponents, memory_exponents, fit_sizes, ratio_size,
                                      speed_ratio, memory_ratio, agreement)


def _summary_record(result):
    return {
        "time_exponents": result.time_exponents,
        "memory_exponents": result.memory_exponents,
        "fit_sizes": result.fit_sizes,
        "ratio_size": result.ratio_size,
        "sum_over_convolution_time": result.speed_ratio,
        "sum_over_convolution_memory": result.memory_ratio,
        "agreement_passed": result.agreement_passed,
        "measurements": [dict(item.__dict__) for item in result.measurements],
    }


# -- formatting --------------------------------------------------------------


def _format_seconds(seconds):
    if seconds is None:
        return "-"
    if seconds < 1e-3:
        return f"{seconds * 1e6:.0f} µs"
    if seconds < 1:
        return f"{seconds * 1e3:.3g} ms"
    return f"{seconds:.3g} s"


def _format_bytes(count):
    if count is None:
        return "-"
    for unit, scale in (("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if abs(count) >= scale:
            return f"{count / scale:.3g} {unit}"
    return f"{count} B"


def _format_exponent(value):
    return "-" if value is None else f"{value:.2f}"


def _cell(item, quantity):
    if item is None:
        return "-"
    if not item.measured:
        return item.status
    return _format_seconds(item.seconds) if quantity == "time" else _format_bytes(item.peak_bytes)


def format_table(result, config):
    """The Markdown report (``integration.md``): measured Table 4.1, exponents, ratios, agreement."""
    sizes = config["sizes"]
    methods = config["methods"]
    lookup = {(item.method, item.size): item for item in result.measurements}
    header_sizes = " | ".join(f"s={size} (N={size ** DIMENSIONS:.2g})" for size in sizes)
    rule = "|---" * (len(sizes) + 1) + "|"
    lines = [
        "# Table 4.1, measured: integrating a random sparse 4-D Fourier signal",
        "",
        f"N = s^4, K = floor(N x {config['density']:g}) coefficients (random support without repetition, values "
        f"uniform in [0, 1), complex128, seed {config['seed']}), integrated over the last two axes: P = s^2 pixels. "
        f"Time: best of up to {config['repeats']} calls. Memory: peak resident memory of the `integrate` call in a "
        f"fresh process (VmHWM minus VmRSS just before the call), including ducc0's and numpy's allocations. "
        f"{config['fft_threads']} FFT threads, {config['cpu_count']} cores.",
        "",
        "## Complexity (Table 4.1) and fitted exponents e (quantity ~ N^e)",
        "",
        "Expected e assumes K = N / 10^4 and P = N^(1/2). Time fits use every measured size; memory fits only sizes "
        f"with a peak above {_format_bytes(MEMORY_FLOOR_BYTES)}.",
        "",
        "| method | Table 4.1 time | expected e | fitted e (time) | Table 4.1 memory | expected e | fitted e (memory) |",
        "|---|---|---|---|---|---|---|",
    ]
    for method in methods:
        name, time_complexity, memory_complexity, time_expected, memory_expected = TABLE_4_1[method]
        memory_sizes = result.fit_sizes["memory"][method]
        if result.memory_exponents[method] is not None:
            memory_note = f" (s = {', '.join(map(str, memory_sizes))})"
        else:
            memory_note = f" (fewer than two peaks above {_format_bytes(MEMORY_FLOOR_BYTES)})"
        lines.append(f"| {name} (`{method}`) | {time_complexity} | {time_expected} | "
                     f"{_format_exponent(result.time_exponents[method])} | {memory_complexity} | {memory_expected} | "
                     f"{_format_exponent(result.memory_exponents[method])}{memory_note} |")
    for quantity, title in (("time", "Time"), ("memory", "Peak memory")):
        lines += ["", f"## {title}", "", f"| method | {header_sizes} |", rule]
        for method in methods:
            cells = " | ".join(_cell(lookup.get((method, size)), quantity) for size in sizes)
            lines.append(f"| {method} | {cells} |")
    lines += ["", "## sum / convolution", ""]
    if result.ratio_size is None:
        lines.append("Not available: 'sum' and 'convolution' were not both measured at any size.")
    else:
        total = lookup[("sum", result.ratio_size)]
        convolution = lookup[("convolution", result.ratio_size)]
        memory = (f"{result.memory_ratio:.3g}x" if result.memory_ratio is not None
                  else "undefined (convolution's peak was below one page)")
        lines.append(f"At s = {result.ratio_size} (N = {result.ratio_size ** DIMENSIONS:.3g}): convolution is "
                     f"{result.speed_ratio:.3g}x faster than sum ({_format_seconds(total.seconds)} vs "
                     f"{_format_seconds(convolution.seconds)}; target >= 1000x) and uses {memory} less peak memory "
                     f"({_format_bytes(total.peak_bytes)} vs {_format_bytes(convolution.peak_bytes)}).")
        if result.ratio_size != max(sizes):
            lines.append(f"(The largest size, s = {max(sizes)}, lacks one of the two; see the notes.)")
    checked = [item for item in result.measurements if item.check_error is not None]
    lines += ["", "## Agreement with 'convolution'", ""]
    if not checked:
        lines.append("Not checked (no size <= check_max_size).")
    else:
        worst = max(item.check_error for item in checked)
        verdict = "passed" if result.agreement_passed else "FAILED"
        lines.append(f"{verdict}: at s <= {config['check_max_size']} every method equals 'convolution' within a relative "
                     f"{CHECK_TOLERANCE:g} (largest error {worst:.2g}), on the measured signal and on the same signal "
                     "with on-plane coefficients added (at K = N / 10^4 few coefficients reach the image).")
    reaching = {item.size: item.contributing_coefficients for item in result.measurements
                if item.contributing_coefficients is not None}
    lines += ["", "## Notes", "",
              f"- The 'time' method evaluates its basis functions in blocks of about {config['time_block_values']} values "
              "(coefficients x output points), so its memory is O(K + P) plus a constant block.",
              "- Coefficients reaching the image (zero integrated coordinates) in the measured signal: "
              + ", ".join(f"s={size}: {reaching.get(size, '-')}" for size in sizes) + "."]
    lines += [f"- s={item.size} {item.method}: {item.status}: {item.reason}" for item in result.measurements if item.reason]
    return "\n".join(lines) + "\n"


CSV_COLUMNS = ("method", "s", "N", "K", "P", "status", "seconds", "run_seconds", "peak_bytes", "baseline_bytes",
               "estimated_bytes", "peak_reset", "contributing_coefficients", "check_error", "reason")


def _csv_text(measurements):
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(CSV_COLUMNS)
    for item in measurements:
        writer.writerow([
            item.method, item.size, item.signal_size, item.coefficients, item.points, item.status,
            "" if item.seconds is None else f"{item.seconds:.6g}",
            ";".join(f"{value:.6g}" for value in item.run_seconds),
            "" if item.peak_bytes is None else item.peak_bytes,
            "" if item.baseline_bytes is None else item.baseline_bytes,
            "" if item.estimated_bytes is None else item.estimated_bytes,
            "" if item.peak_reset is None else item.peak_reset,
            "" if item.contributing_coefficients is None else item.contributing_coefficients,
            "" if item.check_error is None else f"{item.check_error:.3g}",
            item.reason,
        ])
    return buffer.getvalue()


def _plot(measurements, methods, quantity, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as pyplot
    import matplotlib.ticker

    from ..images import save_figure

    figure, axis = pyplot.subplots(figsize=(7, 5))
    sizes = sorted({item.size for item in measurements})
    styles = {"sum": ("o", "-", None), "time": ("s", "-", None), "time-fft": ("D", "--", "none"),
              "convolution": ("^", "-", None)}
    for method in methods:
        marker, line, face = styles[method]
        rows = [item for item in measurements if item.method == method and item.measured]
        if quantity == "time":
            points = [(item.signal_size, item.seconds) for item in rows if item.seconds and item.seconds > 0]
        else:
            points = [(item.signal_size, item.peak_bytes / 2**20) for item in rows if item.peak_bytes and item.peak_bytes > 0]
        if points:
            axis.loglog(*zip(*points), marker=marker, linestyle=line, markerfacecolor=face,
                        label=f"{TABLE_4_1[method][0]} ('{method}')")
    if quantity == "memory":
        axis.axhline(MEMORY_FLOOR_BYTES / 2**20, color="grey", linestyle=":", linewidth=1,
                     label=f"{MEMORY_FLOOR_BYTES // 2**20} MiB (below: allocator noise, not fitted)")
        axis.set_ylabel("peak memory of integrate (MiB)")
        axis.set_title("Figure 4.2: memory of the integration with regard to signal size")
    else:
        axis.set_ylabel("execution time (s)")
        axis.set_title("Figure 4.1: execution time of the integration with regard to signal size")
    axis.set_xscale("log")
    axis.set_yscale("log")
    top = axis.get_ylim()[1]
    for item in measurements:
        if item.method in methods and not item.measured:
            axis.annotate(f"{item.method}: {item.status}", (item.signal_size, top), fontsize=7, rotation=90,
                          va="top", ha="right")
    axis.set_xticks([size ** DIMENSIONS for size in sizes])
    axis.set_xticklabels([f"{size ** DIMENSIONS:.2g}\ns={size}" for size in sizes])
    axis.xaxis.set_minor_locator(matplotlib.ticker.NullLocator())
    axis.set_xlabel("signal size N = s^4 (K = N / 10^4 coefficients, P = s^2 pixels)")
    axis.grid(True, which="major", alpha=0.3)
    if axis.get_legend_handles_labels()[0]:
        axis.legend(fontsize=8)
    save_figure(figure, path, dpi=120, bbox_inches="tight")


if __name__ == "__main__":
    sys.exit(_child_main(sys.argv[1:]))
