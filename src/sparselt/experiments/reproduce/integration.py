"""Chapter 4 of `sparselt reproduce`: Table 4.1 and Figures 4.1/4.2 (the four Fourier integration methods)."""

from __future__ import annotations


from ...report import Section, Table
from ...thesis.findings import judge, table_claim
from ...thesis.numbers import thesis_table
from .common import thesis_figure


def _exponent(value):
    return "-" if value is None else f"N^{value:.2f}"


def table_4_1(result, sizes):
    """Thesis Table 4.1 (its complexities, through :mod:`sparselt.thesis.numbers`) beside our fitted exponents."""
    from ..integration_report import THESIS_ROWS, thesis_complexity

    rows = []
    for method, label in THESIS_ROWS.items():
        time_complexity, memory_complexity = thesis_complexity(method)
        rows.append((label, [time_complexity, _exponent(result.time_exponents.get(method)), memory_complexity,
                             _exponent(result.memory_exponents.get(method))]))
    return Table(caption=f"Table 4.1: {thesis_table('4.1')['caption']} (ours: exponents fitted over "
                         f"s = {', '.join(map(str, sizes))}, N = s^4, K = N / 10^4)",
                 columns=["thesis time", "ours: time ~", "thesis memory", "ours: memory ~"],
                 kinds=["thesis", "ours", "thesis", "ours"], rows=rows, label_header="integration method")


def _seconds(result, method):
    if result.ratio_size is None:
        return None
    try:
        return result.measurement(method, result.ratio_size).seconds
    except KeyError:
        return None


def chapter_4(run):
    """Table 4.1 and Figures 4.1/4.2: the four integration methods' time and memory against N."""
    from ..integration_benchmark import run_integration_benchmark

    sizes = run.scale.integration_sizes
    result = run_integration_benchmark(run.sub("integration"), sizes=sizes, repeats=run.scale.integration_repeats,
                                       overwrite=True, progress=run.progress)
    table = table_4_1(result, sizes)
    verdicts = []
    slow, fast = _seconds(result, "sum"), _seconds(result, "convolution")
    measured = None if slow is None or fast is None else ([slow], [fast])
    finding = judge(table_claim("4.1", "convolution-fastest"), measured,
                    subject=f"s = {result.ratio_size} (N = {result.ratio_size ** 4:,})" if measured else "")
    verdicts.append(finding.sentence + (f" Convolution is {result.speed_ratio:.0f}x faster and uses "
                                        f"{result.memory_ratio:.0f}x less peak memory there."
                                        if result.speed_ratio and result.memory_ratio else ""))
    if result.empty_image_sizes:
        verdicts.append(f"At s = {', '.join(map(str, result.empty_image_sizes))} no coefficient reaches the image: "
                        "those sizes time the integration of an all-zero image.")
    if result.agreement_passed is not None:
        verdicts.append("All four methods give the same integrals (checked against convolution)."
                        if result.agreement_passed else "The methods DISAGREE beyond the tolerance: see integration.md.")
    time_sentence = (f"Ours: convolution {fast:.3g} s against sum {slow:.3g} s at s = {result.ratio_size}."
                     if measured else "")
    return Section(
        title="Chapter 4: Fourier integration",
        introduction="The four ways of integrating a sparse Fourier representation into an image, timed and "
                     "measured for peak memory on random 4-D signals of K = N / 10^4 coefficients (thesis 4.3); "
                     f"sizes: {run.scale.sizes_text('4')}.",
        tables=[table],
        figures=[thesis_figure(run.page_path("integration", "figure_4_1_time.png"), "4.1", "random sparse 4-D signals",
                               [time_sentence]),
                 thesis_figure(run.page_path("integration", "figure_4_2_memory.png"), "4.2", "random sparse 4-D signals",
                               [f"Ours: sum integration needs {result.memory_ratio:.0f}x the peak memory of "
                                f"convolution at s = {result.ratio_size}." if result.memory_ratio else ""])],
        verdicts=verdicts,
        links=[("integration.md (all measurements)", run.page_path("integration", "integration.md")),
               ("integration.csv", run.page_path("integration", "integration.csv"))])


__all__ = ["chapter_4", "table_4_1"]

