"""One contract over every registered method, built-in and plug-in (issue 19; scikit-learn's estimator checks).

Each method runs on the real Cornell box (thin lens, 16x16x4x4 grid) through
Mitsuba, with the renderer wrapped in a sample counter
(:class:`sparselt.methods.contract.SampleCountingScene`). The plug-in is the
documented example, ``examples/median_of_means.py``.
"""

import json
import os
import sys

import numpy as np
import pytest

from sparselt.experiments.compare import ComparisonConfig, compare, validate_config
from sparselt.methods import Budget, ComparisonContext, get_method, load_plugins, method_names
from sparselt.methods.contract import check_method, check_result
from sparselt.rendering.layout import KINDS

EXAMPLES = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "examples")
sys.path.insert(0, EXAMPLES)
PLUGIN = "median_of_means"
load_plugins([PLUGIN])
METHODS = method_names()
SHAPE = (16, 16, 4, 4)
BUDGET = Budget(spp=4, seed=3)


@pytest.fixture(scope="module")
def context():
    from sparselt.rendering import mitsuba_backend
    from sparselt.rendering.layout import path_layout
    from sparselt.rendering.scenes import get_scene

    spec = get_scene("cornell-box").with_lens(0.1, 1000.0)
    scene = mitsuba_backend.MitsubaScene(spec, SHAPE[:2])
    return ComparisonContext(scene=scene, layout=path_layout("dof", 3, thin_lens=True), kind="dof",
                             grid_shape=SHAPE, resolution=SHAPE[:2], max_depth=3)


def test_the_plugin_and_every_built_in_method_are_registered():
    assert PLUGIN in get_method("median-of-means").__module__
    assert {"pt", "cosamp", "oidn", "guided-sft", "median-of-means"} <= set(METHODS)


@pytest.mark.parametrize("name", METHODS)
def test_method_keeps_the_contract(name, context):
    """Image (height, width, 3) float32 and finite; phases that add up to the run's wall time; the path samples
    it reports are those the renderer drew; the same seed gives the same image; options survive JSON."""
    method = get_method(name)
    options = method.options_of(context)
    report = check_method(method, context.with_options(options), BUDGET)
    result = report["result"]
    assert result.image.shape == (16, 16, 3) and result.image.dtype == np.float32
    assert report["drawn"] >= 16 * 16 * BUDGET.spp or name == "sft"  # the SFT's budget is per lattice point
    assert report["drawn"] > 0


@pytest.mark.parametrize("name", METHODS)
def test_kinds_are_refused_as_declared(name):
    method = get_method(name)
    for kind in KINDS:
        shape = SHAPE if kind in ("dof", "indirect") else (16, 16) + (4,) * 8
        config = ComparisonConfig(scene="cornell-box", kind=kind, shape=shape, methods=(name,), spps=(4,),
                                  aperture=0.1 if kind == "dof" else None)
        if kind in method.kinds:
            validate_config(config)
        else:
            with pytest.raises(ValueError, match=f"method '{name}' does not support kind '{kind}'"):
                validate_config(config)


DOF_METHODS = tuple(name for name in METHODS if "dof" in get_method(name).kinds)


def test_options_round_trip_through_compare_json_for_every_method(tmp_path):
    """One comparison of every method of kind dof (and one of kind indirect for the rest): compare.json and each
    cell record hold the options each method ran with; they resolve back to the same objects, and the plug-in's
    rows reach every table and the page."""
    rest = tuple(name for name in METHODS if name not in DOF_METHODS)
    assert rest and all("indirect" in get_method(name).kinds for name in rest)
    other = ComparisonConfig(scene="cornell-box", kind="indirect", shape=SHAPE, methods=("pt",) + rest, spps=(4,),
                             reference_spp=16)
    compare(other, tmp_path / "indirect", progress=False)
    stored_other = json.loads((tmp_path / "indirect" / "compare.json").read_text())["methods"]
    for name, options in other.resolved_options().items():
        assert get_method(name).Options(**stored_other[name]["options"]) == options
    config = ComparisonConfig(scene="cornell-box", kind="dof", shape=SHAPE, methods=DOF_METHODS, spps=(4,),
                              aperture=0.1, focus_distance=1000.0, reference_spp=16,
                              options={"median-of-means": {"groups": "3"}, "*": {"gamma": 0.5}})
    resolved = config.resolved_options()
    result = compare(config, tmp_path / "all", progress=False)
    record = json.loads((tmp_path / "all" / "compare.json").read_text())
    assert record["config"]["identity"]["method_options"] == {name: options.record()
                                                              for name, options in resolved.items()}
    for name in DOF_METHODS:
        method = get_method(name)
        stored = record["methods"][name]["options"]
        assert method.Options(**stored) == resolved[name] == method.options_of(
            ComparisonContext(None, None, "dof", SHAPE, SHAPE[:2], 3, options=stored))
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
