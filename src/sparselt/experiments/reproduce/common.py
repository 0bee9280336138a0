"""What every chapter runner of `sparselt reproduce` shares: its run context, signals, figures with findings."""

from __future__ import annotations

import os
from dataclasses import dataclass

from ...report import Figure
from ...thesis.findings import figure_finding, judge


@dataclass
class ChapterRun:
    """One chapter's run: its scale, the open reproduce folder, and the chapter's own sub-folder.

    Attributes
    ----------
    scale : ReproduceScale
    number : str
        '4' to '8'.
    folder : sparselt.storage.folder.ExperimentFolder
        The reproduce folder (open); the chapter writes its own figures through it.
    path : str
        ``chapterN/``, absolute: each experiment of the chapter lives in a sub-folder of it.
    progress : bool
    """

    scale: object
    number: str
    folder: object
    path: str
    progress: bool = False

    def sub(self, name):
        """The absolute path of an experiment folder of the chapter."""
        return os.path.join(self.path, name)

    def page_path(self, *parts):
        """A path relative to the page (``chapterN/...``)."""
        return "/".join((f"chapter{self.number}",) + parts)

    def write_figure(self, name, figure):
        """Write a matplotlib figure into the chapter folder; return its page path."""
        path = self.page_path(name)
        self.folder.write_figure(path, figure, dpi=110, bbox_inches="tight")
        return path


def thesis_figure(path, numbers, ours="", findings=()):
    """A :class:`~sparselt.report.Figure` under the thesis's caption, with its finding and ours beneath.

    Parameters
    ----------
    path : str
        The image, relative to the page.
    numbers : str or sequence of str
        The thesis figure(s) this image reproduces ('5.2', or ('6.4', '6.5') for one image of both).
    ours : str
        What our image is of (scene, grid, spp), appended to the caption.
    findings : sequence of str
        Our sentences (from :func:`sparselt.thesis.findings.judge` or measured); the thesis's finding comes first.
    """
    numbers = (numbers,) if isinstance(numbers, str) else tuple(numbers)
    records = [figure_finding(number) for number in numbers]
    label = "Figure " + numbers[0] if len(numbers) == 1 else "Figures " + " and ".join(numbers)
    caption = f"{label}: " + " / ".join(dict.fromkeys(record["caption"] for record in records))
    if ours:
        caption += f" (ours: {ours})"
    thesis = " ".join(f"Thesis ({record['section']}): {record['finding']}" for record in records)
    return Figure(path, caption, findings=[thesis] + [finding for finding in findings if finding])


def figure_claim(number, ours, subject=""):
    """Our sentence on the claim thesis Figure ``number`` makes (empty when it makes none)."""
    claim = figure_finding(number).get("claim")
    if claim is None:
        return ""
    return judge(claim, ours, subject=subject).our_sentence


def sampled_signal(scene, kind, shape, spp, folder, name, progress, **lens):
    """A signal sampled into ``folder/name``; a complete one is reused only if it is this very configuration
    and scene (else it is sampled again: the old store stays until the new one is complete)."""
    from ...rendering.acquire import AcquisitionConfig, acquire_signal
    from ...signal import load_signal, signal_status

    path = os.path.join(folder, name)
    config = AcquisitionConfig(scene=scene, kind=kind, shape=tuple(shape), spp=spp, seed=1, **lens)
    if signal_status(path) == "complete":
        signal = load_signal(path)
        digest = config.setup().scene_identity["digest"]
        if signal.meta.get("config") == config.record() and \
                (signal.meta.get("scene_identity") or {}).get("digest") == digest:
            return signal
    return acquire_signal(config, path, overwrite=True, progress=progress)


def grid_text(shape):
    return "x".join(map(str, shape))
