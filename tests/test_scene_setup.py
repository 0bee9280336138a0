"""The one digest and the one scene setup (issue 34): resolution, defaults, validation, identity."""

import hashlib
import json

import numpy as np
import pytest

from sparselt.digest import DIGEST_LENGTH, bytes_digest, canonical, digest, file_digest
from sparselt.rendering.layout import default_shape
from sparselt.rendering.setup import SceneSetup

XML = """<scene version="3.0.0">
  <sensor type="perspective">
    <float name="fov" value="45"/>
    <transform name="to_world"><lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="$width"/><integer name="height" value="24"/></film>
  </sensor>
  <emitter type="constant"><rgb name="radiance" value="1.0"/></emitter>
  <shape type="sphere"/>
</scene>
"""


# ----------------------------------------------------------------------------- digest
def test_digest_is_sha256_of_sorted_json_from_an_independent_computation():
    value = {"b": [1, 2.5, "x"], "a": {"z": None, "y": True}}
    expected = hashlib.sha256(json.dumps(value, sort_keys=True).encode()).hexdigest()
    assert digest(value) == expected
    assert len(expected) == DIGEST_LENGTH


def test_digest_does_not_depend_on_container_or_scalar_types():
    assert digest({"shape": (2, 3), "spp": np.int64(4)}) == digest({"spp": 4, "shape": [2, 3]})
    assert digest({"x": np.array([1.5, 2.0])}) == digest({"x": [1.5, 2.0]})
    assert canonical({"t": (1, 2)}) == {"t": [1, 2]}


def test_digest_tells_values_apart():
    assert digest({"spp": 4}) != digest({"spp": 5})
    assert digest([1, 2]) != digest([2, 1])


def test_digest_refuses_what_json_cannot_hold():
    with pytest.raises(TypeError, match="cannot hash a object"):
        digest({"x": object()})


def test_bytes_and_file_digests_agree_with_hashlib(tmp_path):
    data = bytes(range(256)) * 5000
    path = tmp_path / "blob"
    path.write_bytes(data)
    assert file_digest(path) == bytes_digest(data) == hashlib.sha256(data).hexdigest()
    assert bytes_digest(data[:10], data[10:]) == hashlib.sha256(data).hexdigest()


# ----------------------------------------------------------------------------- default shapes
@pytest.mark.parametrize("kind, depth, expected", [
    ("dof", 3, (40, 30, 16, 16)),
    ("indirect", 3, (40, 30, 16, 16)),
    ("path", 2, (40, 30, 4, 4, 4, 4)),
    ("path", 3, (40, 30) + (4,) * 8),
    ("path-indirect", 2, (40, 30, 4, 4, 4, 4)),
])
def test_default_shape_is_the_film_then_the_kind_default(kind, depth, expected):
    assert default_shape(kind, depth, (40, 30)) == expected


def test_a_setup_without_shape_takes_the_builtin_film_and_records_it():
    setup = SceneSetup("dof-sculptures", kind="dof")
    width, height = setup.spec.default_resolution
    assert setup.grid_shape == (width, height, 16, 16)
    record = setup.validate().record()
    assert record["shape"] == [width, height, 16, 16]
    assert record["shape_given"] is False
    assert SceneSetup("dof-sculptures", kind="dof", shape=(8, 8, 2, 2)).record()["shape_given"] is True


def test_a_scene_file_gives_its_film_resolution_with_its_parameters(tmp_path):
    path = tmp_path / "scene.xml"
    path.write_text(XML)
    setup = SceneSetup(str(path), kind="indirect", parameters={"width": "36"})
    assert setup.film_resolution == (36, 24)
    assert setup.validate().grid_shape == (36, 24, 16, 16)
    other = SceneSetup(str(path), kind="indirect", parameters=(("width", "20"),))
    assert other.grid_shape == (20, 24, 16, 16)
    assert other.digest() != setup.digest()  # the -D parameters are part of the scene's identity


# ----------------------------------------------------------------------------- validation
def test_validation_names_the_bad_value():
    with pytest.raises(ValueError, match="unknown signal kind 'colour'"):
        SceneSetup("cornell-box", kind="colour").validate()
    with pytest.raises(ValueError, match="unknown scene 'no-such-scene'"):
        SceneSetup("no-such-scene", kind="path").validate()
    with pytest.raises(ValueError, match="every shape entry"):
        SceneSetup("cornell-box", kind="path", max_depth=2, shape=(8, 0, 2, 2, 2, 2)).validate()
    with pytest.raises(ValueError, match="has 4 axes but kind 'path' at max depth 2 has 6"):
        SceneSetup("cornell-box", kind="path", max_depth=2, shape=(8, 8, 2, 2)).validate()
    with pytest.raises(ValueError, match="needs a thin-lens camera"):
        SceneSetup("cornell-box", kind="dof", shape=(8, 8, 2, 2)).validate()
    with pytest.raises(ValueError, match="unknown Mitsuba variant 'scalar_rgb'"):
        SceneSetup("cornell-box", kind="path", variant="scalar_rgb").validate()
    with pytest.raises(ValueError, match="built in and takes no parameters"):
        SceneSetup("cornell-box", kind="path", parameters={"width": "3"}).validate()
    with pytest.raises(ValueError, match="max_depth"):
        SceneSetup("cornell-box", kind="path", max_depth=0).validate()


def test_an_aperture_makes_a_pinhole_scene_valid_for_dof_and_changes_its_identity():
    pinhole = SceneSetup("cornell-box", kind="path", max_depth=2)
    lens = SceneSetup("cornell-box", kind="dof", aperture=0.05)
    assert lens.validate().layout().thin_lens
    assert lens.scene_identity["digest"] != pinhole.scene_identity["digest"]


def test_the_setup_digest_follows_every_field():
    base = SceneSetup("cornell-box", kind="path", max_depth=2, shape=(8, 8, 2, 2, 2, 2))
    assert base.digest() == SceneSetup("cornell-box", kind="path", max_depth=2, shape=[8, 8, 2, 2, 2, 2]).digest()
    assert base.digest() != SceneSetup("cornell-box", kind="path", max_depth=2, shape=(8, 8, 2, 2, 2, 4)).digest()
    assert base.digest() != SceneSetup("cornell-box", kind="path", max_depth=2, shape=(8, 8, 2, 2, 2, 2),
                                       variant="cuda_ad_rgb").digest()


# ----------------------------------------------------------------------------- the command line without --shape
WALLS = """  <shape type="rectangle">
    <transform name="to_world"><translate value="0, 0, -1"/><scale value="4"/></transform>
    <bsdf type="diffuse"/>
  </shape>
"""


def _compare(scene, out, *extra):
    from sparselt.cli import main

    return main(["compare", "--scene", str(scene), "-D", "width=16", "--kind", "indirect", "--methods", "pt",
                 "--spp", "2", "--seeds", "1", "--timing-repeats", "1", "--reference-spp", "16", "--out", str(out),
                 "--no-progress", *extra])


def test_compare_on_a_scene_file_without_shape_uses_the_film_and_records_it(tmp_path, capsys):
    """A user comparing images of their own scene gives no grid: the film's resolution and the kind's default."""
    scene = tmp_path / "scene.xml"
    scene.write_text(XML.replace('<shape type="sphere"/>', '<shape type="sphere"><bsdf type="diffuse"/></shape>\n'
                                 + WALLS))
    out = tmp_path / "compare"
    assert _compare(scene, out) == 0, capsys.readouterr().err
    record = json.loads((out / "compare.json").read_text())
    assert record["config"]["shape"] == [16, 24, 16, 16]
    assert record["config"]["resolution"] == [16, 24]


def test_compare_refuses_a_black_reference_with_a_clear_message(tmp_path, capsys):
    """One lone sphere under a constant sky has no one-bounce indirect light: said, exit status 2."""
    scene = tmp_path / "scene.xml"
    scene.write_text(XML)
    assert _compare(scene, tmp_path / "compare") == 2
    assert "is black (every pixel 0" in capsys.readouterr().err
