"""Issue 36: the suite file is checked before anything renders, naming the file, line and key."""

import pytest

from sparselt.cli import main
from sparselt.experiments.standard_suite import SCALES, standard_suite
from sparselt.experiments.suite_config import SuiteError, read_suite

VALID = """\
[suite]
name = "two-scenes"
methods = ["pt", "oidn", "bilateral:sigma_spatial=1.5"]
spp = [4, 16]
seeds = [1, 2]
timing_repeats = 1
reference_spp = 256
resolution = [32, 32]

[[scene]]
name = "box"
scene = "cornell-box"
kind = "path"

[[scene]]
name = "sculptures"
scene = "dof-sculptures"
kind = "dof"
reason = "depth of field"
"""


def write(tmp_path, text, name="suite.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_a_valid_file_gives_every_scene_its_comparison(tmp_path):
    config = read_suite(write(tmp_path, VALID))
    assert [scene.name for scene in config.scenes] == ["box", "sculptures"]
    comparison = config.comparison(config.scenes[1])
    assert comparison.kind == "dof" and comparison.resolution == (32, 32)
    assert comparison.shape == (32, 32, 16, 16)  # the resolution, then the kind's default cells
    assert comparison.methods == ("pt", "oidn", "bilateral:sigma_spatial=1.5")
    assert comparison.reference_spp == 256 and comparison.seeds == (1, 2)


def test_an_unknown_key_names_the_file_line_and_key(tmp_path):
    path = write(tmp_path, VALID.replace("timing_repeats = 1", "timing_repeat = 1"))
    with pytest.raises(SuiteError, match=r"suite\.toml:6: \[suite\] 'timing_repeat': unknown key"):
        read_suite(path)
    path = write(tmp_path, VALID.replace('reason = "depth of field"', 'aperture_radius = 0.1'))
    with pytest.raises(SuiteError, match=r"suite\.toml:19: \[\[scene\]\] #2 'aperture_radius': unknown key"):
        read_suite(path)


def test_a_missing_scene_file_is_refused_with_its_line(tmp_path):
    path = write(tmp_path, VALID.replace('scene = "cornell-box"', 'scene = "scenes/missing.xml"'))
    with pytest.raises(SuiteError, match=r"suite\.toml:12: \[\[scene\]\] #1 'scene': .*missing\.xml"):
        read_suite(path)


def test_a_method_that_cannot_run_a_kind_is_refused_before_anything_renders(tmp_path):
    text = VALID.replace('kind = "path"', 'kind = "path"\nmethods = ["pt", "aaf-dof"]')
    with pytest.raises(SuiteError, match=r"suite\.toml:14: \[\[scene\]\] #1 'methods': .*aaf-dof"):
        read_suite(write(tmp_path, text))
    # The suite's own list, on a scene whose kind one of its methods does not support: the suite's line.
    text = VALID.replace('methods = ["pt", "oidn", "bilateral:sigma_spatial=1.5"]', 'methods = ["pt", "aaf-dof"]')
    with pytest.raises(SuiteError, match=r"suite\.toml:3: \[suite\] 'methods': scene 'box' \(kind path\)"):
        read_suite(write(tmp_path, text))


@pytest.mark.parametrize("change, pattern", [
    (('spp = [4, 16]', 'spp = [4, "16"]'), r":4: \[suite\] 'spp': expected a non-empty list of whole numbers"),
    (('resolution = [32, 32]', 'resolution = [32]'), r":8: \[suite\] 'resolution': expected 2 numbers"),
    (('reference_spp = 256', 'reference_spp = "lots"'), r":7: \[suite\] 'reference_spp': .*\"auto\""),
    (('kind = "dof"', 'kind = "defocus"'), r":18: \[\[scene\]\] #2 'kind': kind 'defocus' is not one of"),
    (('name = "sculptures"', 'name = "box"'), r":16: \[\[scene\]\] #2 'name': scene name 'box' is used twice"),
    (('name = "sculptures"', 'name = "../up"'), r"'name': '\.\./up' is not a name"),
    (('name = "two-scenes"\n', ''), r"\[suite\] needs 'name'"),
])
def test_bad_values_are_refused_naming_the_key(tmp_path, change, pattern):
    with pytest.raises(SuiteError, match=pattern):
        read_suite(write(tmp_path, VALID.replace(*change)))


def test_not_toml_and_no_scenes_are_refused(tmp_path):
    with pytest.raises(SuiteError, match="not a valid TOML file"):
        read_suite(write(tmp_path, "[suite\nname = 1"))
    with pytest.raises(SuiteError, match=r"no \[\[scene\]\] tables"):
        read_suite(write(tmp_path, VALID.split("[[scene]]")[0]))
    with pytest.raises(SuiteError, match="does not exist"):
        read_suite(tmp_path / "nothing.toml")


def test_a_scene_file_is_resolved_relative_to_the_suite_file(tmp_path):
    folder = tmp_path / "suites"
    folder.mkdir()
    (folder / "scenes").mkdir()
    scene = folder / "scenes" / "plane.xml"
    scene.write_text('<scene version="3.0.0"><shape type="sphere"/></scene>')
    text = VALID.replace('scene = "cornell-box"', 'scene = "scenes/plane.xml"')
    config = read_suite(write(folder, text))
    assert config.scenes[0].scene == str(scene)


def test_the_cli_exits_2_naming_the_line(tmp_path, capsys):
    path = write(tmp_path, VALID.replace("seeds = [1, 2]", "seed = [1, 2]"))
    assert main(["suite", str(path), "--out", str(tmp_path / "out")]) == 2
    assert "suite.toml:5: [suite] 'seed': unknown key" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()  # nothing was written
    assert main(["suite", "--out", str(tmp_path / "out")]) == 2
    assert "give a suite file or --suite standard" in capsys.readouterr().err
    assert main(["suite", str(path), "--scale", "quick", "--out", str(tmp_path / "out")]) == 2


@pytest.mark.parametrize("scale", sorted(SCALES))
def test_the_standard_suite_has_ten_scenes_each_with_a_reason_and_its_kinds_methods(scale):
    from sparselt.methods import method_class
    from sparselt.methods.variants import parse_method_variant

    config = standard_suite(scale)
    assert len(config.scenes) >= 10
    assert len({scene.scene for scene in config.scenes}) == len(config.scenes)  # distinct scenes
    assert config.resolution == SCALES[scale].resolution
    for scene in config.scenes:
        assert scene.reason
        assert scene.methods[0] == "pt"
        for row in scene.methods:
            assert scene.kind in method_class(parse_method_variant(row)[0]).kinds
        # every method of the scale that supports the kind runs there
        assert set(scene.methods) == {row for row in SCALES[scale].methods
                                      if scene.kind in method_class(row).kinds} | {"pt"}
    assert {scene.kind for scene in config.scenes} >= {"dof", "indirect", "path"}


def test_the_standard_suite_refuses_unknown_names():
    with pytest.raises(ValueError, match="scale 'huge' is not one of quick, default, paper"):
        standard_suite("huge")
    with pytest.raises(ValueError, match="no scene 'kitchen'"):
        standard_suite("quick", scenes=["kitchen"])
    with pytest.raises(ValueError, match="is not registered|unknown method|not a registered"):
        standard_suite("quick", methods=["pt", "nonesuch"])
