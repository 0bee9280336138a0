"""Deep path layouts on a user's scene file: a default signal grid too large to index is no obstacle to the
methods that never bin samples into it (found by running an outside scene at max depth 6: every method but PT failed).

Real Mitsuba renders at small sizes, fixed seeds.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from sparselt.cli import main
from sparselt.rendering.layout import default_shape, path_layout
from sparselt.rendering.scenes import get_scene

#: A scene as a user writes it (examples/user-scene): point, spot and environment light beside a small area light, a
#: bitmap texture and an OBJ mesh beside the XML, glass and rough gold, Mitsuba's default (Gaussian) pixel filter.
USER_SCENE = Path(__file__).resolve().parents[1] / "examples" / "user-scene" / "scene.xml"

DEPTH = 5


def test_a_path_layout_of_depth_5_has_a_default_grid_beyond_32_bits():
    """The case these tests are about: the kind's default grid at depth 5 is beyond a 32-bit cell index."""
    grid = default_shape("path", DEPTH, (24, 16))
    assert np.prod(np.array(grid, dtype=float)) > 2.0**32


@pytest.fixture(scope="module")
def scene():
    from sparselt.rendering.mitsuba import MitsubaScene

    return MitsubaScene(get_scene("cornell-box"), (24, 16))


def test_samples_drawn_without_cells_are_the_samples_drawn_with_them(scene):
    layout = path_layout("path", 3)
    grid = (24, 16) + (2,) * (len(layout.axes) - 2)
    values, cells, _ = scene.sample_pixels(layout, grid, 4, 7)
    same, none, _ = scene.sample_pixels(layout, grid, 4, 7, cells=False)
    assert none is None and cells is not None
    np.testing.assert_array_equal(values, same)


def test_cells_of_a_grid_beyond_32_bits_are_refused_by_name(scene):
    layout = path_layout("path", DEPTH)
    grid = default_shape("path", DEPTH, (24, 16))
    with pytest.raises(ValueError, match=r"signal grid .* cells.*2\*\*32 - 1.*--shape"):
        scene.sample_pixels(layout, grid, 1, 1)
    values, cells, _ = scene.sample_pixels(layout, grid, 2, 1, cells=False)
    assert cells is None and np.isfinite(values).all() and values.sum() > 0


def test_compare_on_a_user_scene_at_depth_5_runs_every_kind_of_method(tmp_path, capsys):
    """PT, a gradient-domain method (its own kernels), a filter (pixel samples) and OIDN on the user's scene file,
    default grid: every cell recorded, every image finite and close to the reference's brightness."""
    out = tmp_path / "compare"
    status = main(["compare", "--scene", str(USER_SCENE), "--kind", "path", "--max-depth", str(DEPTH),
                   "--resolution", "24,16",
                   "--methods", "pt,gradient-l2,bilateral,oidn", "--spp", "8", "--seeds", "1,2",
                   "--timing-repeats", "1", "--pt-ladder-max-spp", "32", "--reference-spp", "256",
                   "--out", str(out), "--no-progress"])
    assert status == 0, capsys.readouterr().err
    recorded = json.loads((out / "compare.json").read_text())
    assert recorded["config"]["shape"] == list(default_shape("path", DEPTH, (160, 96)))  # the film's, as documented
    import csv

    rows = list(csv.DictReader((out / "results.csv").open()))
    methods = {row["method"] for row in rows}
    assert {"gradient-l2", "bilateral", "oidn"} <= methods
    for row in rows:
        if row["method"] != "pt":
            # Each image's mean brightness against the reference's: 8 spp of a dim scene with a caustic-making
            # sphere; unbiased methods within 25%, which a wrong light (a missed delta emitter) would not be.
            assert 0.75 < float(row["luminance_ratio"]) < 1.25, row
