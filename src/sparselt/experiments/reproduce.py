"""`sparselt reproduce`: the thesis's experiments, chapter by chapter, as one HTML page (issue 14).

Each chapter runner runs (or finds, when a previous run finished it) its
experiments in ``DIR/chapterN/`` and returns a :class:`~sparselt.report.Section`:
the thesis's tables (from :mod:`sparselt.thesis_numbers`) beside our measured
numbers, the figures under the thesis's captions, a verdict written from the
numbers, and the wall time. A finished chapter records its section in
``chapterN/section.json`` so that a rerun only writes the page again.

Chapters reproduced so far: 4 (integration). The others are refused with a
message naming the command that reproduces them today.
"""

from __future__ import annotations

import os
import time
from dataclasses import asdict

from ..provenance import environment_record, read_json, write_json
from ..report import Figure, Section, Table, write_page
from ..thesis_numbers import thesis_table

CHAPTERS = ("4", "5", "6", "7", "8", "all")
SCALES = ("quick", "thesis")
IMPLEMENTED = ("4",)
#: Where each chapter's experiments are today, for the chapters the page does not cover yet.
COMMANDS = {"5": "sparselt analyze", "6": "sparselt table61 / sparselt compare --methods pt,guided-sft",
            "7": "sparselt analyze --gamma", "8": "sparselt compare"}
INTEGRATION_SIZES = {"quick": (16, 24, 32), "thesis": (32, 48, 64, 96, 128)}
_METHOD_ROWS = (("Sum Integration", "sum"), ("Fourier Time Integration (no FFT)", "time"),
                ("Fourier Time Integration (with FFT)", "time-fft"), ("Convolution Integration", "convolution"))


def _check(chapter, scale):
    if str(chapter) not in CHAPTERS:
        raise ValueError(f"chapter must be one of {', '.join(CHAPTERS)}, got {chapter!r}")
    if scale not in SCALES:
        raise ValueError(f"scale must be one of {', '.join(SCALES)}, got {scale!r}")
    chapters = IMPLEMENTED if str(chapter) == "all" else (str(chapter),)
    for number in chapters:
        if number not in IMPLEMENTED:
            raise ValueError(f"chapter {number} is not reproduced by 'sparselt reproduce' yet (chapters: "
                             f"{', '.join(IMPLEMENTED)}); its experiments run with '{COMMANDS[number]}'")
    return chapters


def _exponent(value):
    return "-" if value is None else f"N^{value:.2f}"


def chapter_4(scale, folder, progress):
    """Table 4.1 and Figures 4.1/4.2: the four integration methods' time and memory against N."""
    from .integration_benchmark import run_integration_benchmark

    sizes = INTEGRATION_SIZES[scale]
    result = run_integration_benchmark(os.path.join(folder, "integration"), sizes=sizes,
                                       repeats=2 if scale == "quick" else 5, overwrite=True, progress=progress)
    thesis = {row["label"]: row["cells"] for row in thesis_table("4.1")["rows"]}
    rows = []
    for label, method in _METHOD_ROWS:
        cells = thesis[label]
        rows.append((label, [cells["Time Complexity"]["text"].strip("$"), _exponent(result.time_exponents.get(method)),
                             cells["Memory Complexity"]["text"].strip("$"),
                             _exponent(result.memory_exponents.get(method))]))
    table = Table(caption="Table 4.1: Complexity Comparison of the Analysed Integration Methods "
                          f"(ours: exponents fitted over s = {', '.join(map(str, sizes))}, N = s^4, K = N / 10^4)",
                  columns=["thesis time", "ours: time ~", "thesis memory", "ours: memory ~"],
                  kinds=["thesis", "ours", "thesis", "ours"], rows=rows)
    verdicts = []
    if result.speed_ratio is not None:
        verdicts.append(f"Convolution integration is {result.speed_ratio:.0f}x faster than sum integration at "
                        f"s = {result.ratio_size} (N = {result.ratio_size ** 4:,}) and uses "
                        f"{result.memory_ratio:.0f}x less peak memory: the thesis's ranking holds."
                        if result.memory_ratio else
                        f"Convolution integration is {result.speed_ratio:.0f}x faster than sum integration at "
                        f"s = {result.ratio_size}.")
    if result.agreement_passed is not None:
        verdicts.append("All four methods give the same integrals (checked against convolution)."
                        if result.agreement_passed else "The methods DISAGREE beyond the tolerance: see integration.md.")
    return Section(
        title="Chapter 4: Fourier integration",
        introduction="The four ways of integrating a sparse Fourier representation into an image, timed and "
                     "measured for peak memory on random 4-D signals of K = N / 10^4 coefficients (thesis 4.3).",
        tables=[table],
        figures=[Figure("chapter4/integration/figure_4_1_time.png", "Figure 4.1: Execution time of the integration "
                        "methods against the signal size (ours)"),
                 Figure("chapter4/integration/figure_4_2_memory.png", "Figure 4.2: Peak memory of the integration "
                        "methods against the signal size (ours)")],
        verdicts=verdicts,
        links=[("integration.md (all measurements)", "chapter4/integration/integration.md"),
               ("integration.csv", "chapter4/integration/integration.csv")])


RUNNERS = {"4": chapter_4}


def reproduce(chapter, scale, out, *, progress=True):
    """Run the chapters' experiments into ``out`` and write ``out/index.html``; return its path.

    Raises
    ------
    ValueError
        Unknown chapter or scale, or a chapter not reproduced yet (the message
        names the command that runs its experiments), before anything runs.
    """
    chapters = _check(chapter, scale)
    out = os.fspath(out)
    os.makedirs(out, exist_ok=True)
    say = print if progress else (lambda *arguments, **options: None)
    sections = []
    started = time.perf_counter()
    for number in chapters:
        folder = os.path.join(out, f"chapter{number}")
        record = os.path.join(folder, "section.json")
        if os.path.isfile(record) and read_json(record).get("scale") == scale:
            say(f"reproduce: chapter {number} already done ({scale})")
            sections.append(Section.from_record(read_json(record)["section"]))
            continue
        say(f"reproduce: chapter {number} ({scale})")
        os.makedirs(folder, exist_ok=True)
        start = time.perf_counter()
        section = RUNNERS[number](scale, folder, progress)
        section.seconds = time.perf_counter() - start
        write_json(record, {"scale": scale, "section": asdict(section)})
        sections.append(section)
    path = write_page(os.path.join(out, "index.html"), "sparselt: the thesis's experiments, reproduced", sections,
                      environment_record(),
                      note=f"Scale '{scale}' on {os.cpu_count()} cores; total wall time "
                           f"{time.perf_counter() - started:.1f} s. Thesis values are shaded beige, ours green.")
    say(f"reproduce: wrote {path}")
    return path
