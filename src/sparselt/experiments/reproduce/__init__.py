"""`sparselt reproduce`: the thesis's experiments, chapter by chapter, as one HTML page (issues 14, 21).

Each chapter runner (one module per chapter family: :mod:`.integration` for 4,
:mod:`.sparsity` for 5 and 7, :mod:`.sft` for 6, :mod:`.equal_time` for 8)
runs, or finds finished, its experiments in ``DIR/chapterN/`` and returns a
:class:`~sparselt.report.Section`: the thesis's tables (from
:mod:`sparselt.thesis.numbers`) beside our numbers, every data figure under
the thesis's caption with the thesis's finding and ours beneath it, and
verdicts that compare our numbers with the direction the thesis reports
(:mod:`sparselt.thesis.findings`). A finished chapter records its section in
``cells/chapterN.json`` so that a rerun only writes the page again.

Scales (:mod:`.scales`): ``tiny`` (the tests), ``quick`` (minutes), ``medium``
(1-2 hours, the thesis's 4-D sizes) and ``thesis``.
"""

from __future__ import annotations

import os
import time
from dataclasses import asdict

from ...provenance import environment_record
from ...report import Section, page_html
from ...thesis.scenes import correspondence_text
from ..protocol import Experiment, run_experiment
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


def chapter_8_rows(methods):
    """Extra rows of chapter 8's comparison: method names or variants (``cosamp:gamma=0.5``), checked now.

    Raises
    ------
    ValueError
        A malformed variant, an unknown method or option, a value the option
        refuses (:func:`~sparselt.methods.variants.parse_method_variant`), or
        a method without depth of field (chapter 8's kind).
    """
    from ...methods import method_class, parse_method_variant

    rows = tuple(dict.fromkeys(str(text).strip() for text in methods))
    for row in rows:
        cls = method_class(parse_method_variant(row)[0])
        if "dof" not in cls.kinds:
            raise ValueError(f"method {row!r} does not support depth of field (kind 'dof'), chapter 8's comparison")
    return rows


def _duration(minutes):
    return f"{minutes:.0f} min" if minutes < 90 else f"{minutes / 60:.1f} h"


RUNNERS = {"4": chapter_4, "5": chapter_5, "6": chapter_6, "7": chapter_7, "8": chapter_8}


def reproduce(chapter, scale, out, *, progress=True, overwrite=False, plugins=(), methods=()):
    """Run the chapters' experiments into ``out`` and write ``out/index.html``; return its path.

    ``out`` is an :class:`~sparselt.storage.folder.ExperimentFolder` whose
    identity is the scale (and the plug-in methods, when any): chapters may
    be added by later runs, but a folder of the other scale is refused
    (``overwrite`` replaces it), so results of different scales never mix.
    Each chapter is a cell; its experiments live in ``chapterN/``, each in
    its own folder or signal store.

    ``plugins`` are modules (``--plugin``) whose methods join chapter 8's
    equal-time comparison (those that support depth of field); ``methods``
    are more rows of it: method names or variants ``METHOD:NAME=VALUE``
    (:func:`chapter_8_rows`), each a row named as written.

    Raises
    ------
    ValueError
        Unknown chapter or scale, a folder of another scale or holding foreign
        files, a plug-in that cannot be used, before anything runs.
    """
    path = run_experiment(ReproduceExperiment(chapter, scale, plugins=plugins, methods=methods, progress=progress),
                          out, overwrite=overwrite, progress=progress)
    if progress:
        print(f"reproduce: wrote {path}")
    return path


class ReproduceExperiment(Experiment):
    """``sparselt reproduce`` as an experiment: one cell per chapter (its record is the chapter's
    :class:`~sparselt.report.Section`; its experiments live in ``chapterN/``); the report is ``index.html``.

    Parameters are those of :func:`reproduce`; :meth:`validate` checks them
    and loads the plug-ins.
    """

    kind = "reproduce"
    cell_unit = "chapter"

    def __init__(self, chapter, scale, *, plugins=(), methods=(), progress=True):
        self.chapter, self.scale, self.plugins, self.methods = chapter, scale, tuple(plugins), tuple(methods)
        self.progress = progress
        self.chapters, self.extra, self.skipped = None, (), ()

    def validate(self):
        self.chapters = _check(self.chapter, self.scale)
        extra, self.skipped = plugin_methods_for_chapter_8(self.plugins)
        self.extra = tuple(dict.fromkeys(extra + chapter_8_rows(self.methods)))  # variants (METHOD:NAME=VALUE) too

    def identity(self):
        identity = {"scale": self.scale}
        if self.extra:
            identity["plugin_methods"] = sorted(self.extra)
        return identity

    def _minutes(self):
        """The expected minutes of the chapters run, at this scale on 2 cores."""
        sizes = get_scale(self.scale)
        return sum(sizes.minutes[number] for number in self.chapters)

    def prepare(self):
        """Say how long the scale takes (from 10 minutes on) and which plug-in methods cannot run; start the clock
        of the page's total wall time."""
        sizes = get_scale(self.scale)
        minutes = self._minutes()
        if minutes >= 10:
            print(f"reproduce: the {self.scale} scale takes about {_duration(minutes)} on 2 cores (chapters "
                  + ", ".join(f"{number}: {_duration(sizes.minutes[number])}" for number in self.chapters)
                  + "); rerun the same command to resume after an interruption", flush=True)
        if self.skipped and self.progress:
            print(f"reproduce: plug-in methods {', '.join(self.skipped)} do not support depth of field (chapter 8): "
                  "not run")
        return {"started": time.perf_counter()}

    def plan(self):
        return [f"chapter{number}" for number in self.chapters]

    def run_cell(self, name, state, folder):
        """Run chapter ``name``'s experiments quietly into ``chapterN/``; record its section and its seconds."""
        number = name[len("chapter"):]
        run = ChapterRun(get_scale(self.scale), number, folder, folder.claim_folder(name))
        start = time.perf_counter()
        # Only chapter 8 runs a general equal-time comparison that other methods can join.
        extras = {"plugin_methods": self.extra} if number == "8" and self.extra else {}
        section = RUNNERS[number](run, **extras)
        section.seconds = time.perf_counter() - start
        return {"scale": self.scale, "section": asdict(section)}

    def report(self, folder, state, records):
        """``index.html``: every chapter's section, in chapter order; returns its path."""
        sections = [Section.from_record(records[name]["section"]) for name in self.plan()]
        return folder.write_text("index.html", page_html(
            folder.path, "sparselt: the thesis's experiments, reproduced", sections, environment_record(),
            note=f"Scale '{self.scale}' on {os.cpu_count()} cores; total wall time "
                 f"{time.perf_counter() - state['started']:.1f} s (chapters found finished are not rerun; expected "
                 f"at this scale on 2 cores: {_duration(self._minutes())}). Seeds: signals and methods 1, "
                 f"references 0. Scenes: {correspondence_text()}. Thesis values are shaded beige, ours green."))


__all__ = ["CHAPTERS", "CHAPTER_8_METHODS", "RUNNERS", "SCALES", "ReproduceExperiment", "chapter_8_rows",
           "plugin_methods_for_chapter_8", "reproduce", "table_4_1"]
