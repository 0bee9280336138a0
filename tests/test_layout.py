"""Primary-sample-space layouts of the four signal kinds (pure Python, no renderer)."""

import pytest

from sparselt.rendering.layout import KINDS, path_layout


@pytest.mark.parametrize("depth", [1, 2, 3, 4, 5])
def test_path_has_two_plus_four_per_bounce_axes(depth):
    layout = path_layout("path", depth)
    assert len(layout.axes) == 2 + 4 * (depth - 1)
    assert layout.axes[:2] == ("x", "y")
    assert all(name.startswith(("light", "bsdf")) for name in layout.axes[2:])


@pytest.mark.parametrize("depth", [2, 3, 4])
def test_path_indirect_has_the_same_dimensionality_as_path(depth):
    assert len(path_layout("path-indirect", depth).axes) == len(path_layout("path", depth).axes)
    layout = path_layout("path-indirect", depth)
    assert not layout.vertices[0].next_event and not layout.count_camera_emission
    assert layout.vertices[-1] == type(layout.vertices[-1])(next_event=False, count_emission_hit=True)


def test_thesis_path_signal_has_ten_axes():
    assert len(path_layout("path", 3).axes) == 10


def test_four_dimensional_kinds():
    assert path_layout("dof", 3, thin_lens=True).axes == ("x", "y", "lens_u", "lens_v")
    assert path_layout("indirect", 3).axes == ("x", "y", "bsdf1_u", "bsdf1_v")


def test_lobe_choice_has_its_own_dimension_and_is_never_an_axis():
    for kind in KINDS:
        layout = path_layout(kind, 4, thin_lens=True)
        lobes = [name for name in layout.dimensions if name.startswith("lobe")]
        assert len(lobes) == len(layout.vertices)
        assert not set(lobes) & set(layout.axes)
        assert len(set(layout.dimensions)) == len(layout.dimensions)


def test_lens_dimensions_follow_the_image_plane():
    layout = path_layout("path", 3, thin_lens=True)
    assert layout.dimensions[:4] == ("x", "y", "lens_u", "lens_v")
    assert "lens_u" not in layout.axes


@pytest.mark.parametrize("arguments, error, message", [
    (dict(kind="dof", max_depth=3, thin_lens=False), ValueError, "--aperture"),
    (dict(kind="caustics", max_depth=3), ValueError, "path-indirect"),  # the message lists the kinds
    (dict(kind="indirect", max_depth=2), ValueError, "max_depth"),
    (dict(kind="path-indirect", max_depth=1), ValueError, "max_depth"),
    (dict(kind="path", max_depth=0), ValueError, "max_depth"),
], ids=["dof-on-a-pinhole-camera", "unknown-kind", "indirect-depth-2", "path-indirect-depth-1", "path-depth-0"])
def test_path_layout_invalid_input(arguments, error, message):
    with pytest.raises(error, match=message):
        path_layout(**arguments)
