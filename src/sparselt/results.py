"""A comparison's results, loaded from its folder as labelled arrays (``sparselt.load_comparison``).

``sparselt compare`` (thesis 8.1.1) writes one record per finished
``(method, spp, seed)`` cell under ``cells/``. :func:`load_comparison` reads
them, read-only, and gives an :class:`xarray.Dataset` with dimensions
``(method, spp, seed)``: one data variable per metric (``ssim``, ``relmse``,
``flip``, ``luminance_ratio``, ``contrast_ratio``, ``relmse_debiased``,
``relmse_caustic``, ... as the run measured them), per time phase
(``seconds_sampling``, ``seconds_reconstruction``, ``seconds_integration``,
``seconds_other``, ``seconds_total`` and its repeats' ``_min``/``_max``),
``path_samples``, and the equal-time columns (``relmse_pt_equal_time``,
``relmse_ratio``, ``verdict``, ...): every column of ``results.csv``, which is
a view of the same Dataset (:func:`sparselt.report.results.dataset_csv`).
``NaN`` where a cell was not run: path tracing's ladder rungs are at other
spps than the methods' budgets. :func:`load_summary` gives the equal-time
protocol's records (``summary.csv``) as a second Dataset, with dimensions
``(method, spp)``: its values aggregate over seeds, so they have no seed
axis to share.

The equal-time columns are computed from the cells by the one protocol
(:mod:`sparselt.experiments.equal_time`), exactly as ``compare`` computes
them before it writes ``results.csv``. Both Datasets carry the comparison's
scene, kind, relMSE epsilon, reference spp and seed, baseline, the
reference's relMSE floor and the folder's status as attributes, and the
configuration, the methods' records (roles, resolved options), PT's fit and
the provenance (every command that wrote the folder) as JSON text
(``json.loads(dataset.attrs['config'])``), so that a Dataset can be written
to netCDF or Zarr as it is.

References
----------
Thesis 8.1.1 (the equal-time comparison).
"""

from __future__ import annotations

import json
import math
import os

from .report.comparison_rows import baseline_of, in_comparison_order
from .report.results import results_dataset, summary_dataset
from .storage.folder import CELLS, ExperimentFolder

#: The folder kind ``sparselt compare`` writes (its :class:`~sparselt.experiments.compare.ComparisonExperiment`).
COMPARISON_KIND = "compare"
#: The configuration file of a comparison folder (written by ``compare``, read here).
CONFIGURATION_FILE = "compare.json"


def reference_spp(record):
    """The reference spp a comparison's cells were measured against, from its ``compare.json`` record: the
    reference's own (``--reference-spp auto`` resolves it), else the configured number; None if unknown."""
    spp = (record.get("reference") or {}).get("spp")
    if spp is None:
        spp = (record.get("config") or {}).get("reference_spp")
    return spp if isinstance(spp, int) and not isinstance(spp, bool) else None


def report_config(config):
    """What the report reads of a comparison's configuration (``kind``, ``shape``, ``output_resolution``,
    ``seeds``, ``timing_repeats``), from the ``config`` of its ``compare.json`` record: for tables and pages
    rebuilt from a folder (:mod:`sparselt.report.comparison`'s ``table_6``, ``table_8``, ``comparison_section``)."""
    from types import SimpleNamespace

    return SimpleNamespace(kind=config["kind"], shape=config["shape"], output_resolution=tuple(config["resolution"]),
                           seeds=config.get("seeds"), timing_repeats=config.get("timing_repeats"))


def _comparison(folder):
    """``(rows with the equal-time columns, summary records, attributes)`` of a comparison folder, read only."""
    from .experiments.equal_time import judge

    reader = ExperimentFolder(os.fspath(folder), kind=COMPARISON_KIND, identity={})
    path = reader.path
    if not os.path.isdir(path):
        raise ValueError(f"{path!r} is not a sparselt compare folder: "
                         f"{'it is a file' if os.path.exists(path) else 'no such folder'}")
    manifest = reader.read_manifest()
    listed = set(manifest["files"])
    if CONFIGURATION_FILE not in listed or not reader.exists(CONFIGURATION_FILE):
        raise ValueError(f"{path!r} is not a complete sparselt compare folder: it has no {CONFIGURATION_FILE}")
    record = reader.read_json(CONFIGURATION_FILE)
    cells = reader.cells()
    rows = []
    for name, cell in cells.items():
        if f"{CELLS}/{name}.json" not in listed:
            raise ValueError(f"{path!r} holds {CELLS}/{name}.json, which its manifest does not list: sparselt did "
                             "not write it; move it away")
        row = cell.get("row") if isinstance(cell, dict) else None
        if not isinstance(row, dict) or not isinstance(row.get("method"), str) or not all(
                isinstance(row.get(key), int) and not isinstance(row.get(key), bool) for key in ("spp", "seed")):
            raise ValueError(f"{path!r}: {CELLS}/{name}.json is not a comparison cell (it needs a row with a "
                             "method name and integer spp and seed)")
        rows.append(dict(row))
    methods = record.get("methods") or {}
    unknown = sorted({row["method"] for row in rows} - set(methods))
    if unknown:
        raise ValueError(f"{path!r} holds cells of method {unknown[0]!r}, which {CONFIGURATION_FILE} does not "
                         "record")
    baseline = baseline_of(methods)
    config = record.get("config") or {}
    rows = in_comparison_order(rows, [baseline] + list(config.get("methods", [])))
    fit, summary = judge(rows, baseline=baseline, reference_spp=reference_spp(record), bias=record.get("bias"))
    floor = record.get("reference_relmse_floor")
    attributes = {
        "scene": config.get("scene", ""), "kind": config.get("kind", ""),
        "relmse_epsilon": record.get("relmse_epsilon", math.nan),
        "reference_spp": reference_spp(record) or -1, "reference_seed": config.get("reference_seed", -1),
        "baseline": baseline or "", "reference_relmse_floor": math.nan if floor is None else floor,
        "status": manifest["status"], "folder": path,
        "config": json.dumps(config, sort_keys=True), "methods": json.dumps(methods, sort_keys=True),
        "pt_fit": json.dumps(record.get("pt_fit"), sort_keys=True),
        "provenance": json.dumps(manifest["history"], sort_keys=True),
    }
    return rows, fit, summary, attributes


def judged_comparison(folder):
    """A comparison folder's cells judged by the equal-time protocol, as plain records (read only).

    Returns
    -------
    rows : list of dict
        Every finished cell's row with the equal-time columns.
    fit : BaselineFit or None
        PT's fits (:func:`sparselt.experiments.equal_time.judge`).
    summary : list of dict
        One record per (method, spp), ``summary.csv``'s.
    attributes : dict
        As :func:`load_comparison`'s Dataset attributes.

    Raises
    ------
    ValueError
        As :func:`load_comparison`.
    """
    return _comparison(folder)


def load_comparison(folder):
    """A comparison's results as an :class:`xarray.Dataset` with dimensions ``(method, spp, seed)``.

    Parameters
    ----------
    folder : str or os.PathLike
        A ``sparselt compare`` output folder (finished or not: the cells
        finished so far are loaded).

    Returns
    -------
    xarray.Dataset
        One data variable per column of ``results.csv`` (metrics, time
        phases, ``path_samples``, the equal-time columns), ``NaN`` where a
        cell was not run; coordinates ``method`` (names as written, variants
        included, the baseline first), ``spp`` and ``seed`` ascending;
        attributes as the module docstring lists. Each variable's
        ``value_type`` attribute says whether its values are real, integer,
        boolean or text (:mod:`sparselt.report.results`).

    Raises
    ------
    ValueError
        ``folder`` is not a compare folder (no folder, no sparselt manifest,
        a folder of another command, no ``compare.json``), or holds a cell
        record its manifest does not list or that is not a cell's; the
        message names the path.

    Notes
    -----
    Reading takes no lock and writes nothing: the folder's bytes are
    unchanged, and a run still writing it is not disturbed.

    Examples
    --------
    >>> results = sparselt.load_comparison("out/demo/compare")  # doctest: +SKIP
    >>> results.relmse.sel({"method": "cosamp", "spp": 40}).mean("seed")  # doctest: +SKIP

    Select the method with a dict: ``method=`` is xarray's own keyword argument
    of :meth:`xarray.Dataset.sel` (inexact matching), not the dimension.
    """
    rows, _, _, attributes = _comparison(folder)
    return results_dataset(rows, attributes=attributes)


def load_summary(folder):
    """A comparison's equal-time summary (``summary.csv``) as an :class:`xarray.Dataset` over ``(method, spp)``.

    Per method and budget: the median time, the mean relMSE, SSIM and FLIP
    over seeds with 95% intervals, path tracing's values at the same time,
    their ratios with intervals, the verdict, the equal-quality speed-up
    (:func:`sparselt.experiments.equal_time.summarize`), the luminance ratio
    with its interval and the fraction of pixels the bias test finds biased
    (``bias_fraction``, from ``compare.json``'s ``bias``; empty in folders
    written before it). Parameters,
    attributes and errors as :func:`load_comparison`.
    """
    _, _, summary, attributes = _comparison(folder)
    return summary_dataset(summary, attributes=attributes)


__all__ = ["COMPARISON_KIND", "CONFIGURATION_FILE", "judged_comparison", "load_comparison", "load_summary"]
