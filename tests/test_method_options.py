"""Methods' declared options, the plug-in registry and the command line built from them (issue 19)."""

import dataclasses
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from sparselt.cli import main
from sparselt.experiments.compare import ComparisonConfig, resolve_run_options
from sparselt.methods import (
    Budget,
    ComparisonContext,
    Method,
    MethodOptions,
    MethodResult,
    PluginError,
    get_method,
    load_plugins,
    method_class,
    method_names,
    option,
    parse_method_variant,
    resolve_options,
    variant_file_name,
)
from sparselt.methods.contract import check_method
from sparselt.methods.options import describe_options
from sparselt.methods.registry import method_source

SHAPE = (16, 16, 4, 4)
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def run_cli(*arguments, pythonpath=(), cwd=None):
    environment = dict(os.environ, PYTHONPATH=os.pathsep.join([*map(str, pythonpath), os.path.join(ROOT, "src")]))
    return subprocess.run([sys.executable, "-m", "sparselt.cli", *arguments], capture_output=True, text=True,
                          env=environment, cwd=cwd)


# ------------------------------------------------------------------------------------------ declared options
def test_defaults_resolve_per_method_and_per_grid():
    cosamp = resolve_options(method_class("cosamp").Options, {}, grid_shape=SHAPE, owner="cosamp")
    sft = resolve_options(method_class("sft").Options, {}, grid_shape=SHAPE, owner="sft")
    assert cosamp.sparsity == 4096 // 200 and cosamp.gamma == 0.25
    assert sft.sparsity == 1 and sft.alpha == 4.0  # K = N/10^4 rounds to 1 here: another default, another option
    big = resolve_options(method_class("sft").Options, {}, grid_shape=(250, 250, 16, 16), owner="sft")
    assert big.sparsity == 1600


def test_text_values_are_parsed_to_the_declared_type():
    options = resolve_options(method_class("guided-sft").Options, {"map-spp": "3", "mode": "global", "snr": "-2.5"},
                              grid_shape=SHAPE, owner="guided-sft")
    assert (options.map_spp, options.mode, options.snr) == (3, "global", -2.5)
    assert isinstance(options.map_spp, int)


@pytest.mark.parametrize("name, given, error, message", [
    ("cosamp", {"gamma": "0"}, ValueError, r"option cosamp.gamma must be a finite number > 0, got 0"),
    ("cosamp", {"gamma": "abc"}, ValueError, r"option cosamp.gamma must be a finite number > 0, got 'abc'"),
    ("cosamp", {"gamma": True}, TypeError, r"option cosamp.gamma must be a finite number > 0, got True"),
    ("cosamp", {"sparsity": 2049}, ValueError, r"cosamp.sparsity must be an integer in \[1, N/2\] \(here 2048\)"),
    ("cosamp", {"sparsity": 2.5}, TypeError, r"cosamp.sparsity must be an integer"),
    ("cosamp", {"alpha": 4}, ValueError, r"method 'cosamp' has no option 'alpha'; its options: gamma, sparsity"),
    ("pt", {"gamma": 1}, ValueError, r"method 'pt' has no option 'gamma'; its options: none"),
    ("guided-pilot", {"mode": "sideways"}, ValueError, r"guided-pilot.mode must be one of per-pixel, global"),
    ("guided-pilot", {"defensive": 1.5}, ValueError, r"guided-pilot.defensive must be a finite number in \[0, 1\]"),
    ("guided-pilot", {"map_spp": 0}, ValueError, r"guided-pilot.map_spp must be an integer in \[1, 65535\]"),
    ("sft", {"alpha": 0.5}, ValueError, r"sft.alpha must be a finite number >= 1, got 0.5"),
    ("sft", {"snr": float("inf")}, ValueError, r"sft.snr must be a finite number, got inf"),
])
def test_every_refused_value_names_the_option_and_what_is_allowed(name, given, error, message):
    with pytest.raises(error, match=message):
        resolve_options(method_class(name).Options, given, grid_shape=SHAPE, owner=name)


def test_shared_options_are_declared_once():
    """The guided methods' pilot options and the CoSaMP options are one declaration each, inherited."""
    from sparselt.methods.cosamp_reconstruction import CosampOptions
    from sparselt.methods.guided import GuidingOptions

    for name in ("guided-pilot", "guided-cosamp", "guided-bilateral", "guided-sft"):
        assert issubclass(method_class(name).Options, GuidingOptions)
    for name in ("cosamp", "cosamp-thesis", "cosamp-bilateral", "guided-cosamp", "guided-bilateral"):
        assert issubclass(method_class(name).Options, CosampOptions)
    rows = {tuple(row) for name in method_names() for row in describe_options(method_class(name).Options)
            if row[0] == "mode"}
    assert len(rows) == 1  # one help, one default, one range wherever 'mode' appears


def test_run_options_wildcard_and_typos():
    resolved = resolve_run_options(("pt", "cosamp", "guided-cosamp"), {"*": {"gamma": 0.5},
                                                                        "guided-cosamp": {"gamma": 0.3}}, SHAPE)
    assert resolved["cosamp"].gamma == 0.5 and resolved["guided-cosamp"].gamma == 0.3
    assert resolved["pt"].record() == {}
    # Options of a registered method outside this run are not used (a rerun with fewer methods keeps them).
    assert set(resolve_run_options(("pt",), {"cosamp": {"gamma": 0.5}}, SHAPE)) == {"pt"}
    with pytest.raises(ValueError, match="unknown method 'cosmap'"):
        resolve_run_options(("pt",), {"cosmap": {"gamma": 0.5}}, SHAPE)
    with pytest.raises(ValueError, match=r"option '\*.gama' is declared by no registered method"):
        resolve_run_options(("pt",), {"*": {"gama": 0.5}}, SHAPE)
    with pytest.raises(TypeError, match="options must map a method name"):
        resolve_run_options(("pt",), {"cosamp": 0.5}, SHAPE)


def test_stating_a_default_is_the_same_identity_and_another_value_is_not():
    base = ComparisonConfig(scene="cornell-box", kind="dof", shape=SHAPE, methods=("pt", "cosamp"), aperture=0.1)
    stated = dataclasses.replace(base, options={"cosamp": {"gamma": "0.25", "sparsity": 20}})
    other = dataclasses.replace(base, options={"cosamp": {"gamma": 0.5}})
    assert base.identity() == stated.identity() != other.identity()
    assert base.identity()["method_options"]["cosamp"] == {"gamma": 0.25, "sparsity": 20}


def test_an_options_class_must_be_frozen_and_declared():
    @dataclasses.dataclass(frozen=True)
    class Foreign:  # not derived from MethodOptions (a thawed subclass Python refuses itself)
        size: int = option(1, help="a size")

    @dataclasses.dataclass(frozen=True)
    class Undeclared(MethodOptions):
        size: int = 1

    @dataclasses.dataclass(frozen=True)
    class Listy(MethodOptions):
        sizes: list = option(None, help="sizes")

    for options_class, message in ((Foreign, "frozen dataclass derived from"), (Undeclared, "not declared with"),
                                   (Listy, "has type")):
        with pytest.raises(TypeError, match=message):
            MethodOptions.declared.__func__(options_class)


# ------------------------------------------------------------------------------------------ plug-ins
def write_module(folder, name, source):
    (folder / f"{name}.py").write_text(textwrap.dedent(source))
    return name


PLAIN = """
    from sparselt.methods import Method, MethodResult, register
    import numpy as np

    @register
    class {cls}(Method):
        name = {name!r}
        kinds = {kinds!r}
        {extra}
        def run(self, context, budget, timer):
            width, height = context.resolution
            return MethodResult(image=np.zeros((height, width, 3), np.float32), path_samples=0)
"""


@pytest.mark.parametrize("name, kinds, extra, message", [
    ("pt", ("dof",), "", r"method name 'pt' is already registered by 'sparselt.methods.path_tracing'"),
    ("Bad Name", ("dof",), "", r"name must be lower-case words joined by dashes"),
    ("my.method", ("dof",), "", r"name must be lower-case words joined by dashes"),
    ("fine-name", ("fog",), "", r"declares kinds \('fog',\); kinds must be a non-empty tuple of"),
    ("fine-name", "dof", "", r"declares kinds 'dof'"),
    ("fine-name", ("dof",), "baseline = True", r"declares baseline = True, but 'pt' is the baseline already"),
    ("fine-name", ("dof",), "family = 3", r"family must be a word"),
    ("fine-name", ("dof",), "Options = dict", r"must be a frozen dataclass derived from"),
    ("fine-name", ("dof",), "requires = ('thin lens',)", r"requires must be a tuple of sparselt.methods.preconditions"),
])
def test_a_plugin_that_breaks_the_contract_is_named_in_one_line(tmp_path, monkeypatch, name, kinds, extra, message):
    module = write_module(tmp_path, f"plugin_{abs(hash((name, str(kinds), extra)))}",
                          PLAIN.format(cls="Broken", name=name, kinds=kinds, extra=extra))
    monkeypatch.syspath_prepend(str(tmp_path))
    before = method_names()
    with pytest.raises(PluginError, match=message) as raised:
        load_plugins([module])
    assert str(raised.value).startswith(f"plug-in '{module}': ") and "\n" not in str(raised.value)
    assert method_names() == before  # nothing half-registered


def test_a_plugin_that_fails_to_import_or_is_missing_is_named(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(str(tmp_path))
    write_module(tmp_path, "plugin_raises", "raise RuntimeError('no licence server')\n")
    with pytest.raises(PluginError, match=r"plug-in 'plugin_raises' fails to import: RuntimeError: no licence server"):
        load_plugins(["plugin_raises"])
    with pytest.raises(PluginError, match=r"plug-in 'plugin_absent': no module named 'plugin_absent'"):
        load_plugins(["plugin_absent"])
    write_module(tmp_path, "plugin_not_a_method", """
        from sparselt.methods import register

        @register
        class Thing:
            name = "thing"
    """)
    with pytest.raises(PluginError, match=r"plug-in 'plugin_not_a_method': Thing is not a subclass"):
        load_plugins(["plugin_not_a_method"])
    write_module(tmp_path, "plugin_no_run", """
        from sparselt.methods import Method, register

        @register
        class Lazy(Method):
            name = "lazy"
            kinds = ("dof",)
    """)
    with pytest.raises(PluginError, match=r"plug-in 'plugin_no_run': method 'lazy' does not implement run"):
        load_plugins(["plugin_no_run"])


def test_a_plugin_option_whose_default_is_out_of_its_own_range_is_refused(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(str(tmp_path))
    write_module(tmp_path, "plugin_bad_default", """
        from dataclasses import dataclass
        from sparselt.methods import Method, MethodOptions, option, register

        @dataclass(frozen=True)
        class Options(MethodOptions):
            groups: int = option(0, minimum=1, help="groups")

        @register
        class Grouped(Method):
            name = "grouped"
            kinds = ("dof",)
            Options = Options
            def run(self, context, budget, timer):
                pass
    """)
    with pytest.raises(PluginError, match=r"the default of 'groups' is refused: option grouped.groups must be"):
        load_plugins(["plugin_bad_default"])


class _Undercounting(Method):
    """Draws PT samples but reports half of them: the contract must catch it."""

    name = "undercounting"
    kinds = ("dof",)

    def run(self, context, budget, timer):
        image, seconds = context.scene.render_path(budget.spp, context.max_depth, budget.seed)
        timer.seconds["sampling"] += seconds
        width, height = context.resolution
        return MethodResult(image=image, path_samples=width * height * budget.spp // 2)


class _Untimed(_Undercounting):
    """Counts its samples but spends time in no phase."""

    name = "untimed"

    def run(self, context, budget, timer):
        import time

        result = super().run(context, budget, timer)
        time.sleep(0.2)
        width, height = context.resolution
        return dataclasses.replace(result, path_samples=width * height * budget.spp)


class _Random(_Undercounting):
    """Ignores the budget's seed."""

    name = "random"

    def run(self, context, budget, timer):
        width, height = context.resolution
        return MethodResult(image=np.random.default_rng().random((height, width, 3), dtype=np.float32),
                            path_samples=0)


@pytest.fixture(scope="module")
def context():
    from sparselt.rendering.mitsuba import MitsubaScene
    from sparselt.rendering.layout import path_layout
    from sparselt.rendering.scenes import get_scene

    scene = MitsubaScene(get_scene("cornell-box").with_lens(0.1, 1000.0), SHAPE[:2])
    return ComparisonContext(scene=scene, layout=path_layout("dof", 3, thin_lens=True), kind="dof",
                             grid_shape=SHAPE, resolution=SHAPE[:2], max_depth=3)


@pytest.mark.parametrize("method, message", [(_Undercounting(), "reports 512 path samples, the renderer drew 1024"),
                                             (_Untimed(), "is in no phase"),
                                             (_Random(), "the same seed gave another image")])
def test_the_contract_catches_a_method_that_breaks_it(context, method, message):
    with pytest.raises(AssertionError, match=message):
        check_method(method, context, Budget(spp=4, seed=1))


# ------------------------------------------------------------------------------------------ the command line
def test_methods_command_prints_every_option_with_default_and_range(capsys):
    assert main(["methods", "cosamp"]) == 0
    text = capsys.readouterr().out
    for expected in ("cosamp: ", "kinds: dof, indirect", "family: cosamp", "--option cosamp.NAME=VALUE",
                     "gamma", "default 0.25; a finite number > 0; thesis 7.1, 8.1.1",
                     "sparsity", "default N/200; an integer in [1, N/2]; thesis 8.1.1"):
        assert expected in text, expected
    assert main(["methods", "sft"]) == 0
    assert "default N/10^4" in capsys.readouterr().out  # the same name, its own default, another method's option
    assert main(["methods"]) == 0
    listing = capsys.readouterr().out
    assert all(name in listing for name in method_names())


def test_compare_help_lists_the_generated_options(capsys):
    with pytest.raises(SystemExit):
        main(["compare", "--help"])
    text = capsys.readouterr().out
    assert "--option METHOD.NAME=VALUE" in text and "guided-cosamp, guided-bilateral:" in text
    assert "gamma=0.25 sparsity=N/200" in text and "--gamma" not in text


@pytest.mark.parametrize("arguments, message", [
    (["--gamma", "0.3"], "--gamma was replaced by --option METHOD.gamma=VALUE"),
    (["--thesis-faithful"], "--thesis-faithful was removed: run the method cosamp-thesis"),
    (["--option", "gamma=0.3"], "--option takes METHOD.NAME=VALUE"),
    (["--option", "cosamp.gamma"], "--option takes METHOD.NAME=VALUE"),
    (["--option", "cosamp.gamma=0.3", "--option", "cosamp.gamma=0.4"], "is given twice"),
])
def test_bad_option_flags_exit_2_with_the_fix(arguments, message, capsys, tmp_path):
    with pytest.raises(SystemExit) as stopped:
        main(["compare", "--scene", "cornell-box", "--kind", "dof", "--shape", "16,16,4,4",
              "--out", str(tmp_path / "o")] + arguments)
    assert stopped.value.code == 2 and message in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_a_bad_option_value_exits_2_before_anything_is_written(capsys, tmp_path):
    code = main(["compare", "--scene", "cornell-box", "--kind", "dof", "--aperture", "0.1", "--shape", "16,16,4,4",
                 "--methods", "pt,guided-pilot", "--option", "guided-pilot.mode=sideways", "--out",
                 str(tmp_path / "o"), "--no-progress"])
    assert code == 2 and "option guided-pilot.mode must be one of per-pixel, global, got 'sideways'" in \
        capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_plugin_flag_errors_are_one_line_with_exit_2(tmp_path):
    write_module(tmp_path, "plugin_clash", PLAIN.format(cls="Clash", name="cosamp", kinds=("dof",), extra=""))
    for plugin, message in (("plugin_missing", "plug-in 'plugin_missing': no module named 'plugin_missing'"),
                            ("plugin_clash", "plug-in 'plugin_clash': method name 'cosamp' is already registered")):
        for command in (["methods"], ["reproduce", "--out", str(tmp_path / "r")],
                        ["compare", "--scene", "cornell-box", "--kind", "dof", "--shape", "16,16,4,4", "--out",
                         str(tmp_path / "c")]):
            result = run_cli(*command, "--plugin", plugin, pythonpath=[tmp_path])
            assert result.returncode == 2, result.stderr
            assert message in result.stderr and len(result.stderr.strip().splitlines()) == 1, result.stderr
    assert not (tmp_path / "r").exists() and not (tmp_path / "c").exists()


def test_an_installed_plugin_registers_through_its_entry_point(tmp_path):
    """A distribution on the path that declares the entry-point group sparselt.methods, no --plugin needed."""
    write_module(tmp_path, "installed_methods", PLAIN.format(cls="Installed", name="installed-zero", kinds=("dof",),
                                                             extra='description = "an installed plug-in"'))
    info = tmp_path / "installed_methods-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: installed-methods\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text("[sparselt.methods]\nzero = installed_methods\n")
    result = run_cli("methods", "installed-zero", pythonpath=[tmp_path])
    assert result.returncode == 0, result.stderr
    assert "installed-zero: an installed plug-in" in result.stdout and "source: zero = installed_methods" in \
        result.stdout
    (info / "entry_points.txt").write_text("[sparselt.methods]\nbroken = installed_missing\n")
    result = run_cli("methods", pythonpath=[tmp_path])
    assert result.returncode == 2 and "plug-in 'broken = installed_missing (entry point)'" in result.stderr


def test_the_example_plugin_runs_in_compare_and_reaches_every_table(tmp_path):
    out = tmp_path / "mom"
    result = run_cli("compare", "--plugin", "median_of_means", "--scene", "cornell-box", "--kind", "dof",
                     "--aperture", "0.1", "--shape", "16,16,4,4", "--methods", "pt,median-of-means",
                     "--spp", "4,16", "--reference-spp", "64", "--option", "median-of-means.groups=2",
                     "--out", str(out), "--no-progress", pythonpath=[os.path.join(ROOT, "examples")],
                     cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    for name in ("results.csv", "table_8.md", "equal_time.md", "methods.md", "index.html"):
        assert "median-of-means" in (out / name).read_text(), name
    assert "groups=2" in (out / "methods.md").read_text()
    assert (out / "images" / "median-of-means_spp16_seed1.png").exists()


def test_register_and_method_source_for_an_in_process_plugin(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(str(tmp_path))
    write_module(tmp_path, "plugin_fine", PLAIN.format(cls="Fine", name="fine-zero", kinds=("dof", "path"),
                                                       extra=""))
    assert load_plugins(["plugin_fine"]) == ("fine-zero",)
    assert method_source("fine-zero") == "plugin_fine" and get_method("fine-zero").family == "other"
    assert get_method("fine-zero").options.record() == {} and get_method("fine-zero").label == "fine-zero"
    assert load_plugins(["plugin_fine"]) == ("fine-zero",)  # imported once, its methods named again


def test_an_old_style_plugin_is_refused_naming_the_new_signature(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(str(tmp_path))
    write_module(tmp_path, "plugin_old_style", """
        from sparselt.methods import Method, register

        @register
        class Old(Method):
            name = "old-style"
            kinds = ("dof",)
            def run(self, context, budget):
                pass
    """)
    with pytest.raises(PluginError, match=r"plug-in 'plugin_old_style': method 'old-style' defines run\(self, context, "
                                          r"budget\); the signature is run\(self, context, budget, timer\)"):
        load_plugins(["plugin_old_style"])


# ------------------------------------------------------------------------------------------ instances and variants
def test_an_instance_carries_its_resolved_options():
    cosamp = method_class("cosamp")
    assert cosamp({"gamma": "0.5"}, grid_shape=SHAPE).options == cosamp.Options(gamma=0.5, sparsity=20)
    assert cosamp(cosamp.Options(gamma=0.3, sparsity=7)).options.sparsity == 7  # resolved already: kept
    with pytest.raises(TypeError, match=r"method 'cosamp': option 'sparsity' depends on the grid; give grid_shape"):
        cosamp({"gamma": 0.5})
    with pytest.raises(ValueError, match=r"option cosamp.gamma must be a finite number > 0, got -1"):
        cosamp({"gamma": -1}, grid_shape=SHAPE)
    aaf = get_method("aaf-dof:width_scale=0.5")
    assert (aaf.name, aaf.label, aaf.options.width_scale) == ("aaf-dof", "aaf-dof:width_scale=0.5", 0.5)
    assert get_method("aaf-dof").options.width_scale == 1.0  # another instance, its own options


@pytest.mark.parametrize("text, message", [
    ("cosmap:gamma=0.5", r"unknown method 'cosmap'; registered methods: "),
    ("cosamp:gama=0.5", r"method variant 'cosamp:gama=0.5': method 'cosamp' has no option 'gama'; its options: "
                        r"gamma, sparsity"),
    ("cosamp:gamma", r"'gamma' is not NAME=VALUE \(a variant is written METHOD:NAME=VALUE"),
    ("cosamp:gamma=", r"'gamma=' is not NAME=VALUE"),
    ("cosamp:gamma=0.5:gamma=0.3", r"gives option 'gamma' twice"),
    ("cosamp:gamma=zero", r"method variant 'cosamp:gamma=zero': option cosamp.gamma must be a finite number > 0, "
                          r"got 'zero'"),
    ("guided-pilot:mode=sideways", r"option guided-pilot.mode must be one of per-pixel, global, got 'sideways'"),
    ("pt:gamma=1", r"method 'pt' has no option 'gamma'; its options: none"),
    ("", r"a method is written METHOD or METHOD:NAME=VALUE"),
])
def test_a_bad_variant_names_what_is_wrong_and_what_is_allowed(text, message):
    with pytest.raises(ValueError, match=message):
        parse_method_variant(text)


def test_variants_parse_and_name_their_files_one_to_one():
    assert parse_method_variant("cosamp") == ("cosamp", {})
    assert parse_method_variant("aaf-dof:width-scale=0.5:pilot_fraction=1") == (
        "aaf-dof", {"width_scale": "0.5", "pilot_fraction": "1"})
    assert variant_file_name("cosamp") == "cosamp"
    names = ["cosamp:gamma=0.5", "cosamp:gamma=-0.5", "aaf-dof:width_scale=0.5", "x~3A", "x:", "a/b:c=d e"]
    stems = [variant_file_name(name) for name in names]
    assert stems[0] == "cosamp~3Agamma~3D0.5" and len(set(stems)) == len(stems)
    assert all(set(stem) <= set("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789._-~") for stem in stems)


def test_variant_options_take_the_method_options_and_win_over_them():
    config = ComparisonConfig(scene="cornell-box", kind="dof", shape=SHAPE, aperture=0.1,
                              methods=("pt", "cosamp", "cosamp:gamma=0.5", "cosamp:sparsity=10", "guided-cosamp"),
                              options={"*": {"gamma": 0.3}, "cosamp": {"sparsity": 12}})
    resolved = config.resolved_options()
    assert (resolved["cosamp"].gamma, resolved["cosamp"].sparsity) == (0.3, 12)
    assert (resolved["cosamp:gamma=0.5"].gamma, resolved["cosamp:gamma=0.5"].sparsity) == (0.5, 12)
    assert (resolved["cosamp:sparsity=10"].gamma, resolved["cosamp:sparsity=10"].sparsity) == (0.3, 10)
    assert resolved["guided-cosamp"].gamma == 0.3
    assert config.identity()["method_options"]["cosamp:gamma=0.5"] == {"gamma": 0.5, "sparsity": 12}
    same = dataclasses.replace(config, methods=("pt", "cosamp", "cosamp:gamma=0.3"))
    with pytest.raises(ValueError, match=r"methods 'cosamp' and 'cosamp:gamma=0.3' are the same estimator"):
        from sparselt.experiments.compare import validate_config

        validate_config(same)


def test_a_comparison_of_variants_names_each_row_as_written(tmp_path):
    """pt, aaf-dof and aaf-dof at half width: three estimators, rows named as written, files named safely."""
    rows = ("pt", "aaf-dof", "aaf-dof:width_scale=0.5")
    out = tmp_path / "variants"
    code = main(["compare", "--scene", "cornell-box", "--kind", "dof", "--aperture", "0.1", "--shape", "16,16,4,4",
                 "--methods", ",".join(rows), "--spp", "4", "--seeds", "1", "--reference-spp", "16",
                 "--timing-repeats", "1", "--out", str(out), "--no-progress"])
    assert code == 0
    import csv
    import json

    with open(out / "results.csv", newline="") as handle:
        methods = {row["method"] for row in csv.DictReader(handle)}
    assert methods == set(rows)
    record = json.loads((out / "compare.json").read_text())
    assert record["methods"]["aaf-dof:width_scale=0.5"]["options"]["width_scale"] == 0.5
    assert record["methods"]["aaf-dof:width_scale=0.5"]["method"] == "aaf-dof"
    assert "method" not in record["methods"]["aaf-dof"]
    assert record["config"]["identity"]["method_options"]["aaf-dof"]["width_scale"] == 1.0
    cell = json.loads((out / "cells" / "aaf-dof~3Awidth_scale~3D0.5_spp4_seed1.json").read_text())
    assert cell["row"]["method"] == "aaf-dof:width_scale=0.5" and cell["options"]["width_scale"] == 0.5
    assert (out / "images" / "aaf-dof~3Awidth_scale~3D0.5_spp4_seed1.png").exists()
    assert "aaf-dof:width_scale=0.5" in (out / "index.html").read_text()


def test_reproduce_takes_variants_for_chapter_8():
    from sparselt.experiments.reproduce import chapter_8_rows

    assert chapter_8_rows(["cosamp:gamma=0.5", "aaf-dof", "cosamp:gamma=0.5"]) == ("cosamp:gamma=0.5", "aaf-dof")
    with pytest.raises(ValueError, match=r"method 'aaf-indirect' does not support depth of field"):
        chapter_8_rows(["aaf-indirect"])
    with pytest.raises(ValueError, match=r"method 'cosamp' has no option 'gama'"):
        chapter_8_rows(["cosamp:gama=0.5"])
