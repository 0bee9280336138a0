"""`sparselt reproduce`: the thesis's experiments, chapter by chapter, as one HTML page (issues 14, 21).

Each chapter runner (one module per chapter family: :mod:`.integration` for 4,
:mod:`.sparsity` for 5 and 7, :mod:`.sft` for 6, :mod:`.equal_time` for 8)
runs, or finds finished, its experiments in ``DIR/chapterN/`` and returns a
:class:`~sparselt.report.Section`: the thesis's tables (from
:mod:`sparselt.thesis_numbers`) beside our numbers, every data figure under
the thesis's caption with the thesis's finding and ours beneath it, and
verdicts that compare our numbers with the direction the thesis reports
(:mod:`sparselt.thesis_findings`). A finished chapter records its section in
``cells/chapterN.json`` so that a rerun only writes the page again.

Scales (:mod:`.scales`): ``tiny`` (the tests), ``quick`` (minutes), ``medium``
(1-2 hours, the thesis's 4-D sizes) and ``thesis``.
"""

from __future__ import annotations

import os
import time
from dataclasses import asdict

from ...measurement import progress_bar
from ...provenance import environment_record
from ...report import Section, page_html
from ...storage.folder import ExperimentFolder
from .common import ChapterRun
from .equal_time import CHAPTER_8_METHODS, chapter_8
from .integration import chapter_4, table_4_1
from .scales import SCALES, get_scale
from .sft import chapter_6
from .sparsity import chapter_5, chapter_7

CHAPTERS = ("4", "5", "6", "7", "8", "all")


def _check(chapter, scale):
    if str(chapter) not in CHAPTERS:
        raise ValueError(f"chapter must be one of {', '.join(CHAPTERS)}, got {chapter!r}")
    get_scale(scale)
    return CHAPTERS[:-1] if str(chapter) == "all" else (str(chapter),)


def plugin_methods_for_chapter_8(plugins):
    """The plug-in modules' methods that can run in chapter 8's comparison (depth of field); load them first.

    Returns
    -------
    runnable : tuple of str
        Methods of the plug-ins that support kind ``dof``.
    skipped : tuple of str
        Their other methods (another kind only).
    """
    from ...methods import get_method, load_plugins

    added = load_plugins(plugins)
    runnable = tuple(name for name in added if "dof" in get_method(name).kinds)
    return runnable, tuple(name for name in added if name not in runnable)


def _duration(minutes):
    return f"{minutes:.0f} min" if minutes < 90 else f"{minutes / 60:.1f} h"


RUNNERS = {"4": chapter_4, "5": chapter_5, "6": chapter_6, "7": chapter_7, "8": chapter_8}


def reproduce(chapter, scale, out, *, progress=True, overwrite=False, plugins=()):
    """Run the chapters' experiments into ``out`` and write ``out/index.html``; return its path.

    ``out`` is an :class:`~sparselt.storage.folder.ExperimentFolder` whose
    identity is the scale (and the plug-in methods, when any): chapters may
    be added by later runs, but a folder of the other scale is refused
    (``overwrite`` replaces it), so results of different scales never mix.
    Each chapter is a cell; its experiments live in ``chapterN/``, each in
    its own folder or signal store.

    ``plugins`` are modules (``--plugin``) whose methods join chapter 8's
    equal-time comparison (those that support depth of field).

    Raises
    ------
    ValueError
        Unknown chapter or scale, a folder of another scale or holding foreign
        files, a plug-in that cannot be used, before anything runs.
    """
    chapters = _check(chapter, scale)
    extra, skipped = plugin_methods_for_chapter_8(plugins)
    identity = {"scale": scale}
    if extra:
        identity["plugin_methods"] = sorted(extra)
    folder = ExperimentFolder(out, kind="reproduce", identity=identity, overwrite=overwrite)
    folder.inspect()
    sizes = get_scale(scale)
    minutes = sum(sizes.minutes[number] for number in chapters)
    if minutes >= 10:
        print(f"reproduce: the {scale} scale takes about {_duration(minutes)} on 2 cores (chapters "
              + ", ".join(f"{number}: {_duration(sizes.minutes[number])}" for number in chapters)
              + "); rerun the same command to resume after an interruption", flush=True)
    say = print if progress else (lambda *arguments, **options: None)
    if skipped:
        say(f"reproduce: plug-in methods {', '.join(skipped)} do not support depth of field (chapter 8): not run")
    sections = []
    started = time.perf_counter()
    with folder.open():
        # One progress display for the whole run: a bar over the chapters; the experiments inside run quietly.
        bar = progress_bar(progress, total=len(chapters), description="reproduce", unit="piece")
        try:
            for number in chapters:
                if bar is not None:
                    bar.set_postfix_str(f"chapter {number}")
                record = folder.cell(f"chapter{number}")
                if record is not None:
                    sections.append(Section.from_record(record["section"]))
                else:
                    run = ChapterRun(sizes, number, folder, folder.claim_folder(f"chapter{number}"))
                    start = time.perf_counter()
                    # Only chapter 8 runs a general equal-time comparison that other methods can join.
                    extras = {"plugin_methods": extra} if number == "8" and extra else {}
                    section = RUNNERS[number](run, **extras)
                    section.seconds = time.perf_counter() - start
                    folder.record_cell(f"chapter{number}", {"scale": scale, "section": asdict(section)})
                    sections.append(section)
                if bar is not None:
                    bar.update(1)
        finally:
            if bar is not None:
                bar.close()
        path = folder.write_text("index.html", page_html(
            folder.path, "sparselt: the thesis's experiments, reproduced", sections, environment_record(),
            note=f"Scale '{scale}' on {os.cpu_count()} cores; total wall time {time.perf_counter() - started:.1f} s "
                 f"(chapters found finished are not rerun; expected at this scale on 2 cores: {_duration(minutes)}). "
                 "Seeds: signals and methods 1, references 0. Scenes: "
                 "Dragons = dof-sculptures, San Miguel = courtyard, Cornell Box = cornell-box (cornell-caustics for "
                 "the caustics). Thesis values are shaded beige, ours green."))
        folder.complete()
    say(f"reproduce: wrote {path}")
    return path


__all__ = ["CHAPTERS", "CHAPTER_8_METHODS", "RUNNERS", "SCALES", "plugin_methods_for_chapter_8", "reproduce",
           "table_4_1"]
