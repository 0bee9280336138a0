"""What the integration benchmark found and how it is written: measured Table 4.1, Figures 4.1-4.2, CSV, JSON.

Thesis section 4.3 fits ``log(time)`` and ``log(memory)`` against ``log(N)``
to compare with the complexities of Table 4.1. This module holds the results
(one :class:`IntegrationMeasurement` per ``(s, method)``, summarised into an
:class:`IntegrationBenchmarkResult` with the fitted exponents, the
``sum / convolution`` ratios and the agreement verdict) and writes them.

Files written into the benchmark's folder
-----------------------------------------
``integration.csv``
    One row per (method, s): N, K, P, status, best time, every run's time,
    peak memory, baseline, estimate, the coefficients reaching the image (in
    the measured signal and in the uniform draw), the largest value of the
    timed call's image, agreement error, reason.
``integration.md``
    The measured Table 4.1: time and memory per method and ``s``, fitted
    exponents next to Table 4.1's complexities, ``sum / convolution``
    ratios at the largest ``s``, and per ``s`` how many coefficients reach
    the image (a warning names every size whose image is all zero).
``figure_4_1_time.png``, ``figure_4_2_memory.png``
    Time and peak memory against ``N``, log-log, one line per method
    (thesis Figures 4.1 and 4.2).
``config.json``
    The resolved configuration, :func:`~sparselt.provenance.environment_record`
    and the summary results.

Every file goes through the benchmark's
:class:`~sparselt.storage.folder.ExperimentFolder`; every table is a
:class:`~sparselt.report.Table`; the thesis's complexities come from
:mod:`sparselt.thesis.numbers` (Table 4.1), never typed here.

References
----------
Thesis chapter 4 (sections 4.1-4.4, Table 4.1, Figures 4.1-4.2).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from ..report import Table, markdown_document
from ..thesis.numbers import thesis_text
from .integration_signal import DIMENSIONS

CHECK_TOLERANCE = 1e-9
MEMORY_FLOOR_BYTES = 4 * 2**20

#: The row of thesis Table 4.1 that describes each integration method.
THESIS_ROWS = {
    "sum": "Sum Integration",
    "time": "Fourier Time Integration (no FFT)",
    "time-fft": "Fourier Time Integration (with FFT)",
    "convolution": "Convolution Integration",
}
#: The exponent ``e`` of ``N^e`` that Table 4.1's complexities imply with ``K = N / 10^4`` and
#: ``P = N^(1/2)`` (thesis 4.3): ``(time, memory)`` per method. Our derivation, not a printed value.
EXPECTED_EXPONENTS = {
    "sum": ("1 (N log N with the inverse FFT)", "1"),
    "time": ("1.5", "0.5 to 1"),
    "time-fft": ("1 (N log N)", "1"),
    "convolution": ("0.5", "0.5 to 1"),
}


def thesis_complexity(method):
    """The time and memory complexity thesis Table 4.1 prints for ``method``.

    Parameters
    ----------
    method : {'sum', 'time', 'time-fft', 'convolution'}

    Returns
    -------
    tuple of str
        ``(time, memory)`` as printed, without the LaTeX dollars, e.g.
        ``('O(P \\log(P))', 'O(K + P)')`` for ``'convolution'``; read through
        :func:`sparselt.thesis.numbers.thesis_text`.

    Raises
    ------
    ValueError
        An unknown method; the message lists the known ones.
    """
    if method not in THESIS_ROWS:
        raise ValueError(f"thesis Table 4.1 has no row for method {method!r}; methods: {', '.join(THESIS_ROWS)}")
    return tuple(thesis_text("4.1", THESIS_ROWS[method], column).strip("$")
                 for column in ("Time Complexity", "Memory Complexity"))


CSV_COLUMNS = ("method", "s", "N", "K", "P", "status", "seconds", "run_seconds", "peak_bytes", "baseline_bytes",
               "estimated_bytes", "peak_reset", "contributing_coefficients", "uniform_contributing_coefficients",
               "image_max", "check_error", "reason")

REPORT_FILES = ("integration.csv", "integration.md", "figure_4_1_time.png", "figure_4_2_memory.png", "config.json")


@dataclass(frozen=True)
class IntegrationMeasurement:
    """One ``(s, method)`` measurement.

    ``status`` is ``'measured'``, ``'skipped'`` (estimated memory above what was
    available; ``reason`` says how much) or ``'failed'`` (the child process
    died or raised; ``reason`` says how). ``seconds`` is the best of
    ``run_seconds``; ``peak_bytes`` is ``VmHWM - VmRSS`` around the first
    call; ``contributing_coefficients`` the coefficients that reach the
    image (integrated coordinates zero), ``uniform_contributing_coefficients``
    those that did in the uniform draw before the benchmark's
    ``minimum_reaching`` moved any onto the plane; ``image_max`` the largest
    ``|value|`` of the image the timed call returned; ``check_error`` the
    largest difference from ``'convolution'`` relative to the output scale
    (``None`` when not checked).
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
    uniform_contributing_coefficients: int | None = None
    image_max: float | None = None
    check_error: float | None = None

    @property
    def measured(self):
        return self.status == "measured"


@dataclass(frozen=True)
class IntegrationBenchmarkResult:
    """Everything :func:`~sparselt.experiments.integration_benchmark.run_integration_benchmark` measured and wrote.

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
    empty_image_sizes : tuple of int
        The sizes whose measured signal has no coefficient reaching the image:
        every method there was timed integrating an all-zero image.
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
    empty_image_sizes: tuple = ()
    files: dict = field(default_factory=dict)

    def measurement(self, method, size):
        """The measurement of ``method`` at ``s = size``."""
        for item in self.measurements:
            if item.method == method and item.size == size:
                return item
        raise KeyError(f"no measurement of {method!r} at s={size}")


# -- the summary -------------------------------------------------------------


def fit_exponent(points):
    """The exponent ``e`` of ``value ~ size^e``, least squares in log-log.

    Parameters
    ----------
    points : list of tuple
        ``(size, value)`` pairs, both positive.

    Returns
    -------
    float or None
        ``None`` with fewer than two points.
    """
    if len(points) < 2:
        return None
    sizes, values = zip(*points)
    return float(np.polyfit(np.log(sizes), np.log(values), 1)[0])


def summarise(measurements, sizes, methods):
    """Fitted exponents, ``sum / convolution`` ratios and the agreement verdict.

    Parameters
    ----------
    measurements : tuple of IntegrationMeasurement
    sizes : sequence of int
        The values of ``s`` measured.
    methods : sequence of str
        The integration methods measured.

    Returns
    -------
    IntegrationBenchmarkResult
        Without ``files``. Memory is fitted only over peaks above
        ``MEMORY_FLOOR_BYTES`` (below it, page and allocator noise dominate).
    """
    time_exponents, memory_exponents = {}, {}
    fit_sizes = {"time": {}, "memory": {}}
    for method in methods:
        rows = [item for item in measurements if item.method == method and item.measured]
        timed = [item for item in rows if item.seconds and item.seconds > 0]
        heavy = [item for item in rows if item.peak_bytes is not None and item.peak_bytes > MEMORY_FLOOR_BYTES]
        time_exponents[method] = fit_exponent([(item.signal_size, item.seconds) for item in timed])
        memory_exponents[method] = fit_exponent([(item.signal_size, item.peak_bytes) for item in heavy])
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
                                      speed_ratio, memory_ratio, agreement, empty_image_sizes(measurements))


def reaching_coefficients(measurements):
    """Size -> the coefficients reaching the image in its measured signal (sizes with a measurement only)."""
    return {item.size: item.contributing_coefficients for item in measurements
            if item.contributing_coefficients is not None}


def empty_image_sizes(measurements):
    """The sizes whose measured signal has no coefficient reaching the image, ascending."""
    return tuple(sorted(size for size, count in reaching_coefficients(measurements).items() if count == 0))


def summary_record(result):
    """The summary results as stored in ``config.json``.

    Parameters
    ----------
    result : IntegrationBenchmarkResult

    Returns
    -------
    dict
        JSON-able: exponents, fit sizes, ratios, agreement and every measurement.
    """
    return {
        "time_exponents": result.time_exponents,
        "memory_exponents": result.memory_exponents,
        "fit_sizes": result.fit_sizes,
        "ratio_size": result.ratio_size,
        "sum_over_convolution_time": result.speed_ratio,
        "sum_over_convolution_memory": result.memory_ratio,
        "agreement_passed": result.agreement_passed,
        "empty_image_sizes": list(result.empty_image_sizes),
        "reaching_coefficients": {str(size): count for size, count in
                                  reaching_coefficients(result.measurements).items()},
        "measurements": [dict(item.__dict__) for item in result.measurements],
    }


# -- formatting --------------------------------------------------------------


def format_seconds(seconds):
    """``seconds`` in µs, ms or s, three significant digits; ``'-'`` for ``None``."""
    if seconds is None:
        return "-"
    if seconds < 1e-3:
        return f"{seconds * 1e6:.0f} µs"
    if seconds < 1:
        return f"{seconds * 1e3:.3g} ms"
    return f"{seconds:.3g} s"


def format_bytes(count):
    """``count`` bytes in GiB, MiB, KiB or B, three significant digits; ``'-'`` for ``None``."""
    if count is None:
        return "-"
    for unit, scale in (("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if abs(count) >= scale:
            return f"{count / scale:.3g} {unit}"
    return f"{count} B"


def format_exponent(value):
    """A fitted exponent with two decimals; ``'-'`` for ``None``."""
    return "-" if value is None else f"{value:.2f}"


def progress_line(item):
    """One line about a finished measurement, for standard error.

    Parameters
    ----------
    item : IntegrationMeasurement

    Returns
    -------
    str
    """
    head = f"s={item.size:<4d} N={item.signal_size:<10.3g} {item.method:<12s}"
    if not item.measured:
        return f"{head} {item.status}: {item.reason}"
    check = "" if item.check_error is None else f", agreement error {item.check_error:.2g}"
    return (f"{head} {format_seconds(item.seconds)} (best of {len(item.run_seconds)}), "
            f"peak {format_bytes(item.peak_bytes)}{check}")


def _cell(item, quantity):
    if item is None:
        return "-"
    if not item.measured:
        return item.status
    return format_seconds(item.seconds) if quantity == "time" else format_bytes(item.peak_bytes)


def complexity_table(result, config):
    """Thesis Table 4.1 beside the fitted exponents (a :class:`~sparselt.report.Table`).

    Per method: Table 4.1's time and memory complexity (through
    :func:`thesis_complexity`), the exponent they imply
    (:data:`EXPECTED_EXPONENTS`) and the exponent fitted to our measurements.
    """
    rows = []
    for method in config["methods"]:
        time_complexity, memory_complexity = thesis_complexity(method)
        time_expected, memory_expected = EXPECTED_EXPONENTS[method]
        memory_sizes = result.fit_sizes["memory"][method]
        if result.memory_exponents[method] is not None:
            memory_note = f" (s = {', '.join(map(str, memory_sizes))})"
        else:
            memory_note = f" (fewer than two peaks above {format_bytes(MEMORY_FLOOR_BYTES)})"
        rows.append((f"{THESIS_ROWS[method]} (`{method}`)", [
            time_complexity, time_expected, format_exponent(result.time_exponents[method]), memory_complexity,
            memory_expected, format_exponent(result.memory_exponents[method]) + memory_note]))
    fitted = sorted({size for sizes in result.fit_sizes["time"].values() for size in sizes})
    over = f", time fitted over s = {', '.join(map(str, fitted))}" if fitted else ""
    return Table(
        caption=f"Complexity (Table 4.1) and fitted exponents e (quantity ~ N^e){over}", label_header="method",
        columns=["Table 4.1 time", "expected e", "fitted e (time)", "Table 4.1 memory", "expected e",
                 "fitted e (memory)"],
        kinds=["thesis", "", "ours", "thesis", "", "ours"], rows=rows,
        notes=["Expected e assumes K = N / 10^4 and P = N^(1/2). Time fits use every measured size; memory fits only "
               f"sizes with a peak above {format_bytes(MEMORY_FLOOR_BYTES)}."])


def measurement_table(result, config, quantity):
    """Time (``quantity='time'``) or peak memory (``'memory'``) per method and ``s`` (a :class:`~sparselt.report.Table`)."""
    sizes = config["sizes"]
    lookup = {(item.method, item.size): item for item in result.measurements}
    return Table(
        caption="Time" if quantity == "time" else "Peak memory", label_header="method",
        columns=[f"s={size} (N={size ** DIMENSIONS:.2g})" for size in sizes], kinds=["ours"] * len(sizes),
        rows=[(method, [_cell(lookup.get((method, size)), quantity) for size in sizes]) for method in config["methods"]])


def reaching_table(result, config):
    """Per ``s``: the coefficients that reach the image, expected and drawn uniformly, and in the measured signal.

    Returns
    -------
    Table or None
        ``None`` when nothing was measured.
    """
    sizes = [size for size in config["sizes"] if any(item.size == size and item.contributing_coefficients is not None
                                                     for item in result.measurements)]
    if not sizes:
        return None
    first = {}
    for item in result.measurements:
        if item.contributing_coefficients is not None:
            first.setdefault(item.size, item)
    convolution = {item.size: item for item in result.measurements if item.method == "convolution" and item.measured}

    def expected(item):
        return f"{item.coefficients * item.points / item.signal_size:.2g}"

    def optional(value, text=str):
        return "-" if value is None else text(value)

    rows = [
        ("K (coefficients)", [str(first[size].coefficients) for size in sizes]),
        ("on the plane, uniform draw: expected (K P / N)", [expected(first[size]) for size in sizes]),
        ("on the plane, uniform draw: drawn", [optional(first[size].uniform_contributing_coefficients)
                                               for size in sizes]),
        ("on the plane, measured signal (reach the image)", [str(first[size].contributing_coefficients)
                                                             for size in sizes]),
        ("largest |value| of the timed convolution's image",
         [optional(getattr(convolution.get(size), "image_max", None), lambda value: f"{value:.3g}") for size in sizes]),
    ]
    minimum = config.get("minimum_reaching", 0)
    how = (f"Where the uniform draw has fewer than min({minimum}, K) there, off-plane coefficients (uniformly chosen, "
           "values kept) are moved to free plane frequencies until it has: a deviation from the thesis's uniform draw "
           "that leaves N, K and P unchanged (see sparselt.experiments.integration_signal)." if minimum else
           "The uniform draw is used as it is (minimum_reaching = 0).")
    return Table(caption="Coefficients reaching the image (integrated coordinates zero)", label_header="per s",
                 columns=[f"s={size}" for size in sizes], kinds=["ours"] * len(sizes), rows=rows,
                 notes=[f"Only coefficients on the integration plane (P = s^2 of the N = s^4 frequencies) reach the "
                        f"image: a uniform draw of K = N x {config['density']:g} puts K P / N there on average. {how}"])


def empty_image_warning(result):
    """The warning for sizes whose timed integrations produced an all-zero image; ``None`` when there are none."""
    if not result.empty_image_sizes:
        return None
    return (f"at s = {', '.join(map(str, result.empty_image_sizes))} no coefficient reaches the image: every method "
            "there was timed integrating an all-zero image. Raise minimum_reaching (at least 1) or the sizes.")


def format_table(result, config):
    """The Markdown report (``integration.md``): measured Table 4.1, exponents, ratios, agreement.

    Parameters
    ----------
    result : IntegrationBenchmarkResult
    config : dict
        The resolved configuration (``sizes``, ``methods``, ``density``,
        ``seed``, ``repeats``, ``fft_threads``, ``cpu_count``,
        ``check_max_size``, ``time_block_values``).

    Returns
    -------
    str
    """
    sizes = config["sizes"]
    lookup = {(item.method, item.size): item for item in result.measurements}
    introduction = "\n".join([
        "# Table 4.1, measured: integrating a random sparse 4-D Fourier signal",
        "",
        f"N = s^4, K = floor(N x {config['density']:g}) coefficients (random support without repetition, values "
        f"uniform in [0, 1), complex128, seed {config['seed']}), integrated over the last two axes: P = s^2 pixels. "
        f"Time: best of up to {config['repeats']} calls. Memory: peak resident memory of the `integrate` call in a "
        f"fresh process (VmHWM minus VmRSS just before the call), including ducc0's and numpy's allocations. "
        f"{config['fft_threads']} FFT threads, {config['cpu_count']} cores."])
    if config.get("minimum_reaching"):
        introduction += (f" Deviation from the thesis's uniform draw: at least min({config['minimum_reaching']}, K) "
                         "coefficients lie on the integration plane, so that the image is not all zero (see "
                         "'Coefficients reaching the image').")
    warning = empty_image_warning(result)
    if warning is not None:
        introduction += f"\n\n**Warning:** {warning}"
    ratio = ["## sum / convolution", ""]
    if result.ratio_size is None:
        ratio.append("Not available: 'sum' and 'convolution' were not both measured at any size.")
    else:
        total = lookup[("sum", result.ratio_size)]
        convolution = lookup[("convolution", result.ratio_size)]
        memory = (f"{result.memory_ratio:.3g}x" if result.memory_ratio is not None
                  else "undefined (convolution's peak was below one page)")
        ratio.append(f"At s = {result.ratio_size} (N = {result.ratio_size ** DIMENSIONS:.3g}): convolution is "
                     f"{result.speed_ratio:.3g}x faster than sum ({format_seconds(total.seconds)} vs "
                     f"{format_seconds(convolution.seconds)}; target >= 1000x) and uses {memory} less peak memory "
                     f"({format_bytes(total.peak_bytes)} vs {format_bytes(convolution.peak_bytes)}).")
        if result.ratio_size != max(sizes):
            ratio.append(f"(The largest size, s = {max(sizes)}, lacks one of the two; see the notes.)")
    checked = [item for item in result.measurements if item.check_error is not None]
    agreement = ["## Agreement with 'convolution'", ""]
    if not checked:
        agreement.append("Not checked (no size <= check_max_size).")
    else:
        worst = max(item.check_error for item in checked)
        verdict = "passed" if result.agreement_passed else "FAILED"
        agreement.append(f"{verdict}: at s <= {config['check_max_size']} every method equals 'convolution' within a "
                         f"relative {CHECK_TOLERANCE:g} (largest error {worst:.2g}), on the measured signal and on the "
                         "same signal with on-plane coefficients added (at K = N / 10^4 few coefficients reach the "
                         "image).")
    notes = ["## Notes", "",
             f"- The 'time' method evaluates its basis functions in blocks of about {config['time_block_values']} "
             "values (coefficients x output points), so its memory is O(K + P) plus a constant block."]
    notes += [f"- s={item.size} {item.method}: {item.status}: {item.reason}" for item in result.measurements if item.reason]
    return markdown_document(introduction, complexity_table(result, config), measurement_table(result, config, "time"),
                             measurement_table(result, config, "memory"), reaching_table(result, config),
                             "\n".join(ratio), "\n".join(agreement), "\n".join(notes))


def measurements_table(measurements):
    """``integration.csv``'s table: :data:`CSV_COLUMNS`, one row per measurement (a :class:`~sparselt.report.Table`)."""
    def optional(value, text=str):
        return "" if value is None else text(value)

    rows = []
    for item in measurements:
        rows.append((item.method, [
            item.size, item.signal_size, item.coefficients, item.points, item.status,
            optional(item.seconds, lambda value: f"{value:.6g}"), ";".join(f"{value:.6g}" for value in item.run_seconds),
            optional(item.peak_bytes), optional(item.baseline_bytes), optional(item.estimated_bytes),
            optional(item.peak_reset), optional(item.contributing_coefficients),
            optional(item.uniform_contributing_coefficients), optional(item.image_max, lambda value: f"{value:.6g}"),
            optional(item.check_error, lambda value: f"{value:.3g}"), item.reason]))
    return Table(caption="Integration benchmark measurements", label_header=CSV_COLUMNS[0], columns=list(CSV_COLUMNS[1:]),
                 rows=rows)


def csv_text(measurements):
    """``integration.csv``: a header of ``CSV_COLUMNS`` and one row per measurement.

    Parameters
    ----------
    measurements : sequence of IntegrationMeasurement

    Returns
    -------
    str
    """
    return measurements_table(measurements).csv()


def plot(measurements, methods, quantity):
    """Figure 4.1 (``quantity='time'``) or 4.2 (``'memory'``): the quantity against ``N``, log-log.

    Parameters
    ----------
    measurements : sequence of IntegrationMeasurement
    methods : sequence of str
        One line per method; the others' skips and failures are not annotated.
    quantity : {'time', 'memory'}

    Returns
    -------
    matplotlib.figure.Figure
        The caller writes it (``folder.write_figure``).
    """
    import matplotlib.ticker

    from ..report.plotting import pyplot

    figure, axis = pyplot().subplots(figsize=(7, 5))
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
                        label=f"{THESIS_ROWS[method]} ('{method}')")
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
    return figure


def write_report(folder, result, config, environment):
    """Write every file of the report through the benchmark's folder.

    Parameters
    ----------
    folder : sparselt.storage.folder.ExperimentFolder
        The benchmark's folder, open.
    result : IntegrationBenchmarkResult
        The summary, from :func:`summarise`.
    config : dict
        The resolved configuration; ``sizes``, ``methods`` and the values the
        table quotes.
    environment : dict
        :func:`~sparselt.provenance.environment_record`, stored in ``config.json``.

    Returns
    -------
    result : IntegrationBenchmarkResult
        ``result`` with ``files``: name -> path of every file written.
    table : str
        The Markdown report, as written to ``integration.md``.
    """
    methods = config["methods"]
    table = format_table(result, config)
    folder.write_text("integration.csv", csv_text(result.measurements))
    folder.write_text("integration.md", table)
    folder.write_figure("figure_4_1_time.png", plot(result.measurements, methods, "time"), dpi=120, bbox_inches="tight")
    folder.write_figure("figure_4_2_memory.png", plot(result.measurements, methods, "memory"), dpi=120,
                        bbox_inches="tight")
    folder.write_json("config.json", {"config": config, "environment": environment, "results": summary_record(result)})
    files = {name: folder.path_of(name) for name in REPORT_FILES}
    return dataclasses.replace(result, files=files), table


def measurement_record(item):
    """One measurement as a JSON-able record (a resumable cell of the benchmark's folder)."""
    record = dataclasses.asdict(item)
    record["run_seconds"] = list(item.run_seconds)
    return record


def measurement_from_record(record):
    """The :class:`IntegrationMeasurement` of a :func:`measurement_record`."""
    fields = {field.name for field in dataclasses.fields(IntegrationMeasurement)}
    values = {key: value for key, value in record.items() if key in fields}
    values["run_seconds"] = tuple(values.get("run_seconds") or ())
    return IntegrationMeasurement(**values)
