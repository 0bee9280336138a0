"""`sparselt table61`: the Sparse Fourier Transform on a rendered path space (thesis 6.1, Table 6.1).

For each ``alpha`` the SFT reconstructs the scene's cell-mean signal over the
grid, reading lattice points through the renderer (``spp`` path samples
each, every one counted), and the image is integrated from the recovered
spectrum (:mod:`sparselt.recovery.path_space`). Beside the thesis's sample
counts the table gives what the images are worth: SSIM and relMSE
(epsilon 0.01) against a cached Mitsuba reference, and those of path tracing
given the same number of path samples and the same time.

Two measurements explain the outcome (issue 13, item 5):

* compressibility: the energy share of the ``K`` largest lattice coefficients
  of the fully sampled signal at a smaller grid, at several samples per cell
  (noise flattens the spectrum);
* noise against sample count: the SFT at more samples per lattice point.

Output folder: ``table_6_1.md`` (thesis numbers beside ours), ``table_6_1.csv``,
``compressibility.md``, ``figure_6_1.png`` (reference, SFT, PT at equal
samples), ``images/`` (EXR/PNG/npy), ``cells/`` (one JSON per run: a rerun
resumes), ``table61.json`` (configuration, seeds, versions, git revision), in
an :class:`~sparselt.storage.folder.ExperimentFolder` whose identity is the
full configuration and the scene's content: a rerun with other settings (a
larger shape, say) is refused instead of mixing results.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass
from functools import cached_property

import numpy as np

from ..checks import check_integer, check_positive_finite
from ..images import reference_exposure
from ..methods.base import Budget, ComparisonContext, run_timed, warm_up
from ..methods.registry import get_method
from ..methods.options import resolve_options
from ..methods.sft_reconstruction import SftOptions, reconstruct
from ..provenance import environment_record
from ..recovery.path_space import largest_energy_fraction
from ..rendering import baseline
from ..rendering.baseline import METHOD_SEED_LIMIT
from ..rendering.setup import DEFAULT_MAX_DEPTH, DEFAULT_VARIANT, SceneSetup
from ..storage.cache import usable_cache_directory
from ..thesis.tables import THESIS_SHAPE, table_6_1
from .protocol import Experiment, run_experiment
from .comparison_cells import IMAGES
from .compare import check_reference_spp
from .quality import RELMSE_EPSILON, quality


@dataclass(frozen=True)
class Table61Config:
    """What ``sparselt table61`` runs (see the module docstring)."""

    scene: str
    shape: tuple = THESIS_SHAPE
    kind: str = "path"
    alphas: tuple = (4.0, 16.0, 32.0)
    spp: int = 1
    noise_spps: tuple = (4,)
    sparsity: int | None = None
    snr: float = 10.0
    seed: int = 1
    reference_spp: int = 1024
    max_depth: int = DEFAULT_MAX_DEPTH
    compressibility_shape: tuple | None = None
    compressibility_spps: tuple = (1, 16, 64)
    variant: str = DEFAULT_VARIANT
    scene_parameters: tuple = ()  # values of a scene file's $name parameters (-D name=value), sorted
    aperture: float | None = None
    focus_distance: float | None = None

    @cached_property  # resolved once per configuration: its scene, identity and loading share it
    def setup(self):
        """The :class:`~sparselt.rendering.setup.SceneSetup` of the experiment: scene, parameters, lens, kind, grid."""
        return SceneSetup(scene=self.scene, kind=self.kind, shape=self.shape, max_depth=self.max_depth,
                          parameters=self.scene_parameters, aperture=self.aperture,
                          focus_distance=self.focus_distance, variant=self.variant)

    def record(self):
        record = {key: list(value) if isinstance(value, tuple) else value for key, value in asdict(self).items()}
        for name in ("aperture", "focus_distance"):  # recorded only when given: earlier folders' identities stay
            if record[name] is None:
                del record[name]
        return record


def validate(config):
    """Every check that needs no renderer; ValueError/TypeError naming the bad value."""
    if len(config.shape) >= 2:  # the SFT's own bounds first: they are tighter than the setup's
        if min(config.shape[:2]) < 11:
            raise ValueError(f"the image plane {tuple(config.shape[:2])} must be at least 11x11 pixels (the SSIM "
                             "window)")
        size = math.prod(config.shape)
        if size >= 2**31:
            raise ValueError(f"shape {tuple(config.shape)} has {size} cells; the SFT supports at most 2**31 - 1")
    config.setup.validate()  # kind, depth, shape, scene, parameters, lens: the scene setup's one check
    size = math.prod(config.shape)
    if not config.alphas:
        raise ValueError("give at least one alpha")
    for alpha in config.alphas:
        check_positive_finite(alpha, "alpha")
        if alpha < 1:
            raise ValueError(f"alpha must be at least 1 (B = alpha K buckets), got {alpha}")
    for spp in (config.spp,) + tuple(config.noise_spps):
        check_integer("samples per lattice point", spp, 1, 2**16 - 1)
    sparsity = max(1, round(size * 1e-4)) if config.sparsity is None else config.sparsity  # 0 is refused, not the default
    check_integer("sparsity (K)", sparsity, 1, size // 2)
    check_reference_spp(tuple(config.shape[:2]), config.reference_spp)
    check_integer("seed", config.seed, 0, METHOD_SEED_LIMIT - 1)  # above it: the reference's passes
    if config.compressibility_shape is not None:
        if len(config.compressibility_shape) != len(config.shape):
            raise ValueError(f"compressibility shape {config.compressibility_shape} needs {len(config.shape)} axes")
        for size in config.compressibility_shape:
            check_integer("every compressibility shape entry", size, 1)
    return sparsity


def _default_compressibility_shape(shape):
    """A grid the machine samples fully in seconds: the image plane at a quarter, the other axes halved."""
    return tuple(max(1, size // 4) for size in shape[:2]) + tuple(max(1, size // 2) for size in shape[2:])


def run_table61(config, out, *, progress=True):
    """Run the experiment into folder ``out`` (resuming finished runs); return the rows.

    Raises
    ------
    ValueError
        A kind or shape the oracle cannot evaluate, samples per point <= 0,
        alpha < 1, K larger than the grid allows: before any sampling.
    """
    return run_experiment(Table61Experiment(config), out, progress=progress)


class Table61Experiment(Experiment):
    """``sparselt table61`` as an experiment: one cell per (alpha, samples per point) run of the SFT, and one for
    the compressibility measurement; the report is Table 6.1, the compressibility table and Figures 6.1/6.2."""

    kind = "table61"
    cell_unit = "run"

    def __init__(self, config):
        self.config = config
        self.sparsity = None

    def validate(self):
        self.sparsity = validate(self.config)

    def identity(self):
        return dict(self.config.record(), sparsity=self.sparsity, relmse_epsilon=RELMSE_EPSILON)

    def scene_identity(self):
        return self.config.setup.scene_identity

    def prepare(self):
        """The reference's cache checked (it cannot be used: nothing starts), then the scene loaded."""
        usable_cache_directory(baseline.reference_cache_directory())
        loaded = self.config.setup.load(tuple(self.config.shape[:2]))
        return loaded.scene, loaded.layout

    def run_cells(self, folder, state, *, progress):
        scene, layout = state
        say = print if progress else (lambda *arguments, **options: None)
        return _run_table61(folder, self.config, self.config.setup.spec, scene, layout, self.sparsity, say, progress)

    def report(self, folder, state, records):
        """Table 6.1 beside ours, the compressibility table, Figures 6.1/6.2; returns the runs' rows."""
        _write_table(folder, self.config, records["rows"], self.sparsity)
        _write_compressibility(folder, self.config, records["compressibility"], self.sparsity)
        _figure(folder, records["rows"], records["exposure"])
        return records["rows"]


def _run_table61(folder, config, spec, scene, layout, sparsity, say, progress):
    resolution = tuple(config.shape[:2])
    given = {"sparsity": sparsity, "snr": config.snr}
    folder.write_json("table61.json", {"config": config.record(), "sparsity": sparsity,
                                       "relmse_epsilon": RELMSE_EPSILON, "provenance": environment_record()})
    reference, reference_record = baseline.cached_reference(scene, config.kind, spp=config.reference_spp,
                                                            max_depth=config.max_depth, seed=0, progress=progress)
    exposure = reference_exposure(reference)
    folder.write_image(f"{IMAGES}/reference", reference, exposure=exposure)
    pt = get_method("pt")
    base = ComparisonContext(scene=scene, layout=layout, kind=config.kind, grid_shape=tuple(config.shape),
                             resolution=resolution, max_depth=config.max_depth)
    warm_up(pt, base)
    pixels = resolution[0] * resolution[1]
    pt_rate = _pt_rate(pt, base, pixels, config.seed)

    runs = [(alpha, config.spp) for alpha in config.alphas]
    runs += [(config.alphas[0], spp) for spp in config.noise_spps if spp != config.spp]
    rows = []
    for alpha, spp in runs:
        name = f"alpha{alpha:g}_spp{spp}"
        done = folder.cell(name)
        if done is not None:
            rows.append(done)
            say(f"table61: {name} already done")
            continue
        say(f"table61: SFT alpha {alpha:g}, {spp} path samples per lattice point, K = {sparsity} of "
            f"N = {math.prod(config.shape)}")
        options = resolve_options(SftOptions, dict(given, alpha=alpha), grid_shape=config.shape, owner="sft")
        start = time.perf_counter()
        result = reconstruct(base, spp, config.seed, options)
        image = result.image()
        seconds = time.perf_counter() - start
        # One PT launch takes at most 2**16 - 1 spp (then the reference's own noise dominates anyway).
        equal_samples_spp = min(max(1, round(result.path_samples / pixels)), 2**16 - 1)
        equal_time_spp = min(max(1, int(seconds * pt_rate / pixels)), 2**16 - 1)
        pt_samples = run_timed(pt, base, Budget(spp=equal_samples_spp, seed=config.seed)).image
        pt_time = run_timed(pt, base, Budget(spp=equal_time_spp, seed=config.seed)).image
        row = {
            "alpha": alpha, "samples_per_point": spp, "sparsity": sparsity, "cells": math.prod(config.shape),
            "support_samples": result.support_samples, "magnitude_samples": result.magnitude_samples,
            "total_samples": result.path_samples, "samples_per_pixel": result.path_samples / pixels,
            "lattice_points": result.cells, "fraction_of_signal": result.cells / math.prod(config.shape),
            "seconds": seconds, "seconds_sampling": result.seconds["sampling"],
            "seconds_reconstruction": result.seconds["reconstruction"],
            "stop_reasons": [r.stop_reason for r in result.results],
            "coefficients": [int(s.indices.size) for s in result.spectra],
            "sft": quality(image, reference), "pt_equal_samples_spp": equal_samples_spp,
            "pt_equal_samples": quality(pt_samples, reference), "pt_equal_time_spp": equal_time_spp,
            "pt_equal_time": quality(pt_time, reference),
        }
        folder.write_image(f"{IMAGES}/sft_{name}", image, exposure=exposure)
        folder.write_image(f"{IMAGES}/pt_equal_samples_{name}", pt_samples, exposure=exposure)
        folder.record_cell(name, row)
        rows.append(row)
        say(f"table61: {name}: {result.path_samples} path samples ({row['samples_per_pixel']:.1f} per pixel), "
            f"SFT relMSE {row['sft']['relmse']:.3g} vs PT {row['pt_equal_samples']['relmse']:.3g} at equal samples")

    compressibility = _compressibility(config, spec, sparsity, folder, say)
    return {"rows": rows, "compressibility": compressibility, "exposure": exposure}


def _pt_rate(pt, context, pixels, seed):
    """Path samples per second of ``pt`` here (warm), to give PT the SFT's time."""
    spp = 16
    result = run_timed(pt, context, Budget(spp=spp, seed=seed))
    return pixels * spp / max(result.total_seconds, 1e-9)


def _compressibility(config, spec, sparsity, folder, say):
    from ..rendering.acquire import AcquisitionConfig, acquire_signal

    done = folder.cell("compressibility")
    if done is not None:
        return done
    shape = tuple(config.compressibility_shape or _default_compressibility_shape(config.shape))
    size = math.prod(shape)
    fraction = sparsity / math.prod(config.shape)
    rows = []
    for spp in config.compressibility_spps:
        signal = acquire_signal(AcquisitionConfig(scene=config.scene, kind=config.kind, shape=shape, spp=spp,
                                                  seed=config.seed, max_depth=config.max_depth, variant=config.variant),
                                progress=False, scene_spec=spec)
        data = np.asarray(signal.data, dtype=np.float64).mean(axis=-1)  # RGB mean
        row = {"spp": spp, "shape": list(shape)}
        for label, share in (("K/N", fraction), ("10 K/N", 10 * fraction), ("1%", 0.01), ("10%", 0.1)):
            count = max(1, round(share * size))
            row[label] = {"coefficients": count, "energy": largest_energy_fraction(data, count)}
        rows.append(row)
        say(f"table61: compressibility at {shape}, {spp} spp: K/N keeps {row['K/N']['energy']:.1%} of the energy")
    record = {"shape": list(shape), "rows": rows}
    folder.record_cell("compressibility", record)
    return record


def _table_6_1(config, rows, sparsity):
    """Table 6.1 beside ours (:func:`sparselt.thesis.tables.table_6_1`): sample counts, image quality, time per run."""
    return table_6_1(rows, caption_suffix=f", {config.scene} ({config.kind}, grid {'x'.join(map(str, config.shape))}, "
                                          f"K = {sparsity})", epsilon=RELMSE_EPSILON)


def _write_table(folder, config, rows, sparsity):
    """``table_6_1.md`` and ``table_6_1.csv`` (thesis Table 6.1 beside ours) through the experiment's folder."""
    folder.write_table("table_6_1", _table_6_1(config, rows, sparsity))


def _write_compressibility(folder, config, record, sparsity):
    """``compressibility.md`` and ``.csv``: energy share of the largest lattice coefficients per samples per cell."""
    from ..report import Table

    labels = ("K/N", "10 K/N", "1%", "10%")
    table = Table(
        caption=f"How compressible the rendered signal is ({config.scene}, {config.kind}, fully sampled at "
                f"{'x'.join(map(str, record['shape']))})",
        label_header="samples per cell", columns=list(labels), kinds=["ours"] * len(labels),
        rows=[(str(row["spp"]), [f"{row[label]['energy']:.1%} ({row[label]['coefficients']})" for label in labels])
              for row in record["rows"]],
        notes=["Share of the energy (mean removed) in the largest lattice Fourier coefficients (their count in "
               f"parentheses); K/N is the table's sparsity {sparsity} / {math.prod(config.shape)}."])
    folder.write_table("compressibility", table)


def _figure(folder, rows, exposure):
    """Figures 6.1/6.2 (``figure_6_1.png``): reference, the SFT image at the lowest alpha, PT at the same samples."""
    from ..images import srgb_tonemap
    from ..report.plotting import pyplot

    if not rows:
        return
    row = rows[0]
    name = f"alpha{row['alpha']:g}_spp{row['samples_per_point']}"
    pictures = [("reference", "reference"),
                (f"sft_{name}", f"SFT, alpha {row['alpha']:g}: {row['total_samples']:,} samples, "
                                f"relMSE {row['sft']['relmse']:.3g}"),
                (f"pt_equal_samples_{name}", f"PT, same samples ({row['pt_equal_samples_spp']} spp): "
                                             f"relMSE {row['pt_equal_samples']['relmse']:.3g}")]
    figure, axes = pyplot().subplots(1, 3, figsize=(13, 4.8))
    for axis, (file, title) in zip(axes, pictures):
        axis.imshow(srgb_tonemap(np.load(folder.path_of(f"{IMAGES}/{file}.npy")), exposure))
        axis.set_title(title.replace(": ", ":\n", 1), fontsize=11)
        axis.axis("off")
    figure.tight_layout()
    folder.write_figure("figure_6_1.png", figure, dpi=110)
