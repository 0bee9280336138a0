"""One contract over every registered method, built-in and plug-in (issue 19; scikit-learn's estimator checks).

Each method runs on the real Cornell box (thin lens, 16x16x4x4 grid) through
Mitsuba, every path sample counted in the renderer's launch seam
(:func:`sparselt.rendering.mitsuba.count_samples`). The plug-ins are the
documented example, ``examples/median_of_means.py``, and :class:`TwoHalves`
below, which does seed arithmetic as a new user would (``budget.seed + 7919``).
"""

import dataclasses
import json
import os
import sys

import numpy as np
import pytest

from sparselt.cli import main
from sparselt.experiments.compare import ComparisonConfig, compare, validate_config
from sparselt.methods import (
    Budget,
    ComparisonContext,
    Method,
    MethodResult,
    MinimumSpp,
    get_method,
    load_plugins,
    method_class,
    method_names,
    register,
    run_timed,
)
from sparselt.methods.contract import check_method, check_result
from sparselt.rendering.layout import KINDS

EXAMPLES = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "examples")
sys.path.insert(0, EXAMPLES)
PLUGIN = "median_of_means"
load_plugins([PLUGIN])


@register
class TwoHalves(Method):
    """A plug-in as a new user writes it: path tracing in two halves, the second at ``budget.seed + 7919``."""

    name = "two-halves"
    kinds = ("dof", "path")
    description = "path tracing in two halves of the budget, the second with a seed of its own (test plug-in)"
    requires = (MinimumSpp(2, reason="it renders two halves"),)
    warm_up_spp = 2

    def run(self, context, budget, timer):
        first_spp = budget.spp // 2
        second_spp = budget.spp - first_spp
        with timer("sampling"):
            first, _ = context.scene.render_path(first_spp, context.max_depth, budget.seed)
            second, _ = context.scene.render_path(second_spp, context.max_depth, budget.seed + 7919)
        with timer("integration"):
            image = (first.astype(np.float64) * first_spp + second.astype(np.float64) * second_spp) / budget.spp
        width, height = context.resolution
        return MethodResult(image=image.astype(np.float32), path_samples=width * height * budget.spp,
                            details={"halves": [first_spp, second_spp]})


METHODS = method_names()
SHAPE = (16, 16, 4, 4)
BUDGET = Budget(spp=4, seed=3)


@pytest.fixture(scope="module")
def context():
    from sparselt.rendering.mitsuba import MitsubaScene
    from sparselt.rendering.layout import path_layout
    from sparselt.rendering.scenes import get_scene

    spec = get_scene("cornell-box").with_lens(0.1, 1000.0)
    scene = MitsubaScene(spec, SHAPE[:2])
    return ComparisonContext(scene=scene, layout=path_layout("dof", 3, thin_lens=True), kind="dof",
                             grid_shape=SHAPE, resolution=SHAPE[:2], max_depth=3)


def test_the_plugin_and_every_built_in_method_are_registered():
    assert PLUGIN in method_class("median-of-means").__module__
    assert {"pt", "cosamp", "oidn", "guided-sft", "median-of-means", "two-halves"} <= set(METHODS)


@pytest.mark.parametrize("name", METHODS)
def test_method_keeps_the_contract(name, context):
    """Image (height, width, 3) float32 and finite; phases that add up to the run's wall time; the path samples
    it reports are those the renderer drew; the same seed gives the same image; options survive JSON."""
    method = get_method(name, grid_shape=SHAPE)
    report = check_method(method, context, BUDGET)
    result = report["result"]
    assert result.image.shape == (16, 16, 3) and result.image.dtype == np.float32
    assert report["drawn"] >= 16 * 16 * BUDGET.spp or name == "sft"  # the SFT's budget is per lattice point
    assert report["drawn"] > 0


@pytest.mark.parametrize("name", METHODS)
def test_kinds_are_refused_as_declared(name):
    method = method_class(name)
    for kind in KINDS:
        shape = SHAPE if kind in ("dof", "indirect") else (16, 16) + (4,) * 8
        config = ComparisonConfig(scene="cornell-box", kind=kind, shape=shape, methods=(name,), spps=(4,),
                                  aperture=0.1 if kind == "dof" else None)
        if kind in method.kinds:
            validate_config(config)
        else:
            with pytest.raises(ValueError, match=f"method '{name}' does not support kind '{kind}'"):
                validate_config(config)


DOF_METHODS = tuple(name for name in METHODS if "dof" in method_class(name).kinds)


def test_options_round_trip_through_compare_json_for_every_method(tmp_path):
    """One comparison of every method of kind dof (and one of kind indirect for the rest): compare.json and each
    cell record hold the options each method ran with; they resolve back to the same objects, and the plug-in's
    rows reach every table and the page."""
    rest = tuple(name for name in METHODS if name not in DOF_METHODS)
    assert rest and all("indirect" in method_class(name).kinds for name in rest)
    # One seed, one timing run, a short PT ladder: the test is about options, not statistics or times.
    quick = dict(seeds=(1,), timing_repeats=1, pt_ladder_max_spp=16)
    other = ComparisonConfig(scene="cornell-box", kind="indirect", shape=SHAPE, methods=("pt",) + rest, spps=(4,),
                             reference_spp=16, **quick)
    compare(other, tmp_path / "indirect", progress=False)
    stored_other = json.loads((tmp_path / "indirect" / "compare.json").read_text())["methods"]
    for name, options in other.resolved_options().items():
        assert method_class(name).Options(**stored_other[name]["options"]) == options
    config = ComparisonConfig(scene="cornell-box", kind="dof", shape=SHAPE, methods=DOF_METHODS, spps=(4,),
                              aperture=0.1, focus_distance=1000.0, reference_spp=16,
                              options={"median-of-means": {"groups": "3"}, "*": {"gamma": 0.5}}, **quick)
    resolved = config.resolved_options()
    result = compare(config, tmp_path / "all", progress=False)
    record = json.loads((tmp_path / "all" / "compare.json").read_text())
    assert record["config"]["identity"]["method_options"] == {name: options.record()
                                                              for name, options in resolved.items()}
    for name in DOF_METHODS:
        method = method_class(name)
        stored = record["methods"][name]["options"]
        assert method.Options(**stored) == resolved[name] == method(stored, grid_shape=SHAPE).options
        cell = json.loads((tmp_path / "all" / "cells" / f"{name}_spp4_seed1.json").read_text())
        assert cell["options"] == stored
        assert record["methods"][name]["baseline"] == (name == "pt")
    assert resolved["median-of-means"].groups == 3 and resolved["cosamp"].gamma == 0.5
    assert resolved["guided-cosamp"].gamma == 0.5 and not hasattr(resolved["bilateral"], "gamma")
    assert {row["method"] for row in result.rows} == set(DOF_METHODS)
    for name in ("results.csv", "table_8.md", "equal_time.md", "methods.md", "index.html"):
        assert "median-of-means" in (tmp_path / "all" / name).read_text(), name


def test_check_result_names_what_is_wrong(context):
    from sparselt.methods import MethodResult

    method = get_method("pt")
    good = dict(image=np.zeros((16, 16, 3), np.float32), seconds={"sampling": 0.1}, path_samples=5)
    cases = [
        (dict(good, image=np.zeros((16, 15, 3), np.float32)), r"shape \(16, 15, 3\); the comparison needs \(16, 16, 3\)"),
        (dict(good, image=np.zeros((16, 16, 3))), "dtype float64"),
        (dict(good, image=np.full((16, 16, 3), np.nan, np.float32)), "NaN or infinite"),
        (dict(good, seconds={"rendering": 1.0}), r"seconds for \['rendering'\]"),
        (dict(good, seconds={"sampling": -1.0}), "finite number >= 0"),
        (dict(good, path_samples=-1), "path_samples must be an integer >= 0"),
        (dict(good, details={"x": object()}), "details must be JSON-able"),
    ]
    for fields, message in cases:
        with pytest.raises(ValueError, match=message):
            check_result(method, MethodResult(**fields), context, BUDGET)
    with pytest.raises(ValueError, match="returned dict, not a sparselt.methods.MethodResult"):
        check_result(method, good, context, BUDGET)
    seconds = check_result(method, MethodResult(**good), context, BUDGET, wall_seconds=0.5)
    assert seconds == {"sampling": 0.1, "reconstruction": 0.0, "integration": 0.0, "other": pytest.approx(0.4)}


def test_a_run_reports_the_seconds_of_the_timer_it_was_given(context):
    """One signature, run(context, budget, timer): the result's seconds are the harness's timer's; a method that
    returns seconds of its own is refused."""
    result = run_timed(get_method("pt"), context, Budget(spp=2, seed=1))
    assert set(result.seconds) == {"sampling", "reconstruction", "integration", "other"}
    assert result.seconds["sampling"] > 0 and result.total_seconds == pytest.approx(result.seconds["sampling"])

    class OwnSeconds(TwoHalves):
        name = "own-seconds"

        def run(self, context, budget, timer):
            return MethodResult(image=np.zeros((16, 16, 3), np.float32), path_samples=0, seconds={"other": 1.0})

    with pytest.raises(ValueError, match=r"returned MethodResult\(seconds=...\); a method times its phases"):
        run_timed(OwnSeconds(), context, Budget(spp=2, seed=1))


def test_seed_arithmetic_in_a_plugin_works_at_any_seed(context):
    """The warm-up seed is a fixed value that no comparison gives a run; the renderer takes any non-negative
    seed a method derives (folded to 32 bits in its one launch seam): ``2**32 - 1 + 7919`` included."""
    from sparselt.methods import WARM_UP_SEED
    from sparselt.rendering.baseline import METHOD_SEED_LIMIT

    assert WARM_UP_SEED >= METHOD_SEED_LIMIT and WARM_UP_SEED + 7919 < 2**32
    with pytest.raises(ValueError, match="seed"):
        validate_config(ComparisonConfig(scene="cornell-box", kind="dof", shape=SHAPE, aperture=0.1, methods=("pt",),
                                         spps=(4,), seeds=(WARM_UP_SEED,)))
    plugin = get_method("two-halves")
    ordinary = run_timed(plugin, context, Budget(spp=4, seed=3))
    assert ordinary.details == {"halves": [2, 2]} and np.all(np.isfinite(ordinary.image))
    for seed in (WARM_UP_SEED, 2**32 - 1):
        image = run_timed(plugin, context, Budget(spp=4, seed=seed)).image
        assert np.all(np.isfinite(image)) and not np.array_equal(image, ordinary.image)


def test_the_seed_arithmetic_plugin_runs_in_compare(tmp_path):
    config = ComparisonConfig(scene="cornell-box", kind="dof", shape=SHAPE, methods=("pt", "two-halves"),
                              spps=(2, 4), seeds=(1,), aperture=0.1, focus_distance=1000.0, reference_spp=16,
                              timing_repeats=1)
    result = compare(config, tmp_path / "halves", progress=False)
    rows = [row for row in result.rows if row["method"] == "two-halves"]
    assert [row["spp"] for row in rows] == [2, 4] and all(row["path_samples"] == 16 * 16 * row["spp"] for row in rows)
    assert (tmp_path / "halves" / "images" / "two-halves_spp4_seed1.png").exists()
    with pytest.raises(ValueError, match=r"method 'two-halves' needs spp >= 2 \(it renders two halves\), got spp 1"):
        validate_config(dataclasses.replace(config, spps=(1, 4)))


def test_a_method_needing_a_lens_on_a_pinhole_camera_fails_before_the_reference(tmp_path, capsys, monkeypatch):
    """compare --kind dof --methods pt,aaf-dof on the Cornell box's pinhole: exit 2, a message naming the fix,
    no reference rendered and no folder written; with a lens, the same comparison validates."""
    from sparselt.rendering import baseline

    def no_reference(*arguments, **keywords):
        raise AssertionError("a reference was rendered")

    monkeypatch.setattr(baseline, "cached_reference", no_reference)
    out = tmp_path / "pinhole"
    code = main(["compare", "--scene", "cornell-box", "--kind", "dof", "--shape", "16,16,4,4", "--methods",
                 "pt,aaf-dof", "--spp", "4", "--out", str(out), "--no-progress"])
    error = capsys.readouterr().err
    assert code == 2 and "thin-lens camera" in error and "--aperture" in error
    assert not out.exists()
    validate_config(ComparisonConfig(scene="cornell-box", kind="dof", shape=SHAPE, methods=("pt", "aaf-dof"),
                                     spps=(4,), aperture=0.1))
    validate_config(ComparisonConfig(scene="dof-sculptures", kind="dof", shape=SHAPE, methods=("pt", "aaf-dof"),
                                     spps=(4,)))  # a built-in thin-lens scene


def test_every_precondition_is_checked_before_anything_renders(tmp_path, monkeypatch):
    """A requirement of the method that a scene file's camera reveals only when it loads is checked then, still
    before the reference; the others are refused from the configuration alone."""
    from sparselt.methods import MethodSetup, ThinLens
    from sparselt.rendering import baseline

    monkeypatch.setattr(baseline, "cached_reference", lambda *a, **k: (_ for _ in ()).throw(AssertionError("rendered")))
    aaf = get_method("aaf-dof")
    with pytest.raises(ValueError, match=r"method 'aaf-dof' needs a thin-lens camera with an aperture"):
        ThinLens().check(aaf, MethodSetup(kind="dof", grid_shape=SHAPE, resolution=SHAPE[:2], thin_lens=False))
    ThinLens().check(aaf, MethodSetup(kind="dof", grid_shape=SHAPE, resolution=SHAPE[:2], thin_lens=None))  # unknown
    cases = [
        (dict(methods=("pt", "wedge-cosamp:tile=3")), r"option wedge-cosamp.tile=3 \(row 'wedge-cosamp:tile=3'\) "
                                                       r"must divide both image axes of the grid 16x16; choose one of "
                                                       r"1, 2, 4, 8, 16"),
        (dict(methods=("pt", "cosamp"), spps=(1, 4)), r"method 'cosamp' needs spp >= 2"),
        (dict(methods=("pt", "sft"), resolution=(24, 24)), r"method 'sft' needs --resolution to be a multiple"),
        (dict(methods=("pt", "aaf-indirect")), r"method 'aaf-indirect' does not support kind 'dof'"),
    ]
    base = ComparisonConfig(scene="cornell-box", kind="dof", shape=SHAPE, spps=(4,), aperture=0.1, reference_spp=16)
    for changes, message in cases:
        with pytest.raises(ValueError, match=message):
            compare(dataclasses.replace(base, **changes), tmp_path / "refused", progress=False)
        assert not (tmp_path / "refused").exists()


def test_a_grid_too_large_for_the_memory_is_refused_before_anything_renders(tmp_path, capsys, monkeypatch):
    """guided-pilot holds arrays over every grid cell: on the path kind's default grid of a 256x256 film (4^8
    cells per pixel, 4.3 billion cells) it once ran out of memory mid-run; now the comparison is refused, naming
    the grid, the memory it needs and what is available. The same check passes a grid that fits."""
    from sparselt import measurement
    from sparselt.methods import GridMemory, MethodSetup
    from sparselt.rendering import baseline

    monkeypatch.setattr(baseline, "cached_reference", lambda *a, **k: (_ for _ in ()).throw(AssertionError("rendered")))
    out = tmp_path / "huge"
    code = main(["compare", "--scene", "cornell-box", "--kind", "path", "--methods", "pt,guided-pilot", "--spp",
                 "4", "--out", str(out), "--no-progress"])
    error = capsys.readouterr().err
    assert code == 2 and "method 'guided-pilot' holds arrays over every cell of the grid 256x256x4x4x4x4x4x4x4x4" in error
    assert "4,294,967,296 cells" in error and "coarser --shape" in error and not out.exists()
    guided = get_method("guided-pilot")
    requirement = next(entry for entry in guided.requirements() if isinstance(entry, GridMemory))
    setup = MethodSetup(kind="path", grid_shape=(16, 16, 4, 4, 4, 4), resolution=(16, 16))  # 65,536 cells
    monkeypatch.setattr(measurement, "available_memory", lambda: int(65536 * requirement.bytes_per_cell) + 1)
    requirement.check(guided, setup)
    monkeypatch.setattr(measurement, "available_memory", lambda: int(65536 * requirement.bytes_per_cell) - 1)
    with pytest.raises(ValueError, match=r"at most 65,535 cells, e\.g\. --shape 16,16,3,3,3,3$"):
        requirement.check(guided, setup)
    monkeypatch.setattr(measurement, "available_memory", lambda: int(255 * requirement.bytes_per_cell))
    with pytest.raises(ValueError, match=r"at most 255 cells$"):  # not even one cell per lens axis fits
        requirement.check(guided, setup)


COMPOSED = ("aaf-dof+oidn", "gradient-l2+oidn", "two-halves+oidn", "cosamp+oidn:gamma=0.5")


@pytest.mark.parametrize("name", COMPOSED)
def test_a_method_followed_by_the_denoiser_keeps_the_contract(name, context):
    """METHOD+oidn (issue 37, 7): the contract, the method's own path samples, its options and aov_spp, and the
    image is the method's image (same seed) denoised with the aov pass's albedo and normal."""
    from sparselt.filters import oidn_denoise

    method = get_method(name, grid_shape=SHAPE)
    report = check_method(method, context, BUDGET)
    result = report["result"]
    inner = get_method(name.replace("+oidn", ""), grid_shape=SHAPE)
    alone = run_timed(inner, context, BUDGET)
    assert result.path_samples == alone.path_samples
    assert method.family == "denoiser" and result.details["aov_spp"] == 4
    buffers, _ = context.scene.render_aovs(4, BUDGET.seed)
    np.testing.assert_array_equal(result.image, oidn_denoise(alone.image, buffers["albedo"], buffers["normal"]))


def test_compositions_that_mean_nothing_are_refused():
    with pytest.raises(ValueError, match="'oidn' is a denoiser itself"):
        method_class("oidn+oidn")
    with pytest.raises(ValueError, match="unknown denoiser 'nfor2'.*METHOD\\+oidn"):
        method_class("pt+nfor2")
    with pytest.raises(ValueError, match="unknown method 'nothing\\+oidn'.*METHOD\\+oidn"):
        get_method("nothing+oidn")
    with pytest.raises(ValueError, match="has no option 'sigma'"):
        get_method("gradient-l1+oidn:sigma=2")
    assert "gradient-l1+oidn" not in method_names()  # made on use, not listed


def test_a_composed_method_has_a_source():
    from sparselt.methods.registry import method_source

    assert method_source("gradient-l1+oidn") == "sparselt.methods.gradient_domain + sparselt.methods.composition"
