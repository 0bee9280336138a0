"""The one correspondence of the thesis's scenes with ours, and the thesis tables built from it (issue 34)."""

import re

import pytest

from sparselt.rendering.scenes import scene_names
from sparselt.thesis.numbers import thesis_tables
from sparselt.thesis.scenes import (
    EQUAL_TIME_TABLES,
    GUIDING_TABLES,
    PATH_SPACE_ROWS,
    SAN_MIGUEL,
    TABLE_SCENES,
    THESIS_SCENES,
    correspondence_text,
    table_for_scene,
    table_scene,
)
from sparselt.thesis.tables import guiding_table, table_6_1, thesis_guiding_times, thesis_table_6_1, thesis_times


def test_every_table_that_names_a_scene_has_its_scene():
    tables = thesis_tables()["tables"]
    named = {number: re.search(r"for the (.+) scene", table["caption"]) for number, table in tables.items()}
    named = {number: match.group(1) for number, match in named.items() if match}
    assert set(named) == {"6.2", "6.3", "7.1", "7.2", "7.3", "8.1", "8.2"}
    for number, thesis_name in named.items():
        assert table_scene(number).thesis_scene.name == thesis_name, number
    assert set(named) | {"6.1"} == set(TABLE_SCENES)  # Table 6.1 names no scene: the thesis ran the Cornell box


def test_the_path_space_tables_rows_are_covered():
    for number in ("5.1", "5.2"):
        labels = {row["label"][0] for row in thesis_tables()["tables"][number]["rows"]}
        assert labels == set(PATH_SPACE_ROWS), number


def test_our_scenes_are_built_in_and_lenses_only_for_depth_of_field():
    built_in = set(scene_names())
    for record in TABLE_SCENES.values():
        assert set(record.scenes) <= built_in and record.thesis_scene.scene in built_in
        assert record.lens() == (record.thesis_scene.lens() if record.kind == "dof" else {})
    assert table_scene("8.2").lens() == {"aperture": SAN_MIGUEL.aperture, "focus_distance": SAN_MIGUEL.focus_distance}
    assert table_scene("7.3").lens() == {} and table_scene("8.1").lens() == {}
    assert {scene.name for scene in THESIS_SCENES.values()} == {"Cornell Box", "Dragons", "San Miguel"}


def test_tables_for_our_scenes():
    assert table_for_scene("dof-sculptures", EQUAL_TIME_TABLES) == "8.1"
    assert table_for_scene("courtyard", EQUAL_TIME_TABLES) == "8.2"
    assert table_for_scene("cornell-caustics", GUIDING_TABLES) == "6.2" == table_for_scene("cornell-box", GUIDING_TABLES)
    assert table_for_scene("cornell-box", EQUAL_TIME_TABLES) is None
    assert correspondence_text() == ("Dragons = dof-sculptures, San Miguel = courtyard, Cornell Box = cornell-box "
                                     "(cornell-caustics for the caustics)")
    with pytest.raises(ValueError, match=r"thesis table '5.1' reports no single scene; tables with one: 6.1, "):
        table_scene("5.1")


def _row(alpha, scene=None):
    quality = {"ssim": 0.5, "relmse": 0.25}
    row = {"alpha": alpha, "samples_per_point": 1, "support_samples": 10, "magnitude_samples": 5, "total_samples": 15,
           "samples_per_pixel": 1.5, "fraction_of_signal": 0.01, "sft": quality, "pt_equal_samples": quality,
           "pt_equal_time": quality, "seconds": 2.0}
    return dict(row, scene=scene) if scene else row


def test_table_6_1_puts_the_thesis_beside_its_scene_only():
    thesis = thesis_table_6_1()
    single = table_6_1([_row(4.0), _row(2.5)], caption_suffix=", x", epsilon=0.01)
    assert single.caption.startswith("Table 6.1: ") and single.caption.endswith(", x")
    assert [label for label, _ in single.rows] == ["4.0", "2.5"]
    assert single.rows[0][1][8] == str(thesis[4]["total"]) and single.rows[1][1][6:10] == ["-"] * 4
    both = table_6_1([_row(4.0, "cornell-box"), _row(4.0, "courtyard")], caption_suffix="", epsilon=0.01)
    assert [label for label, _ in both.rows] == ["4, cornell-box", "4, courtyard"]
    assert both.rows[0][1][8] == str(thesis[4]["total"]) and both.rows[1][1][6:10] == ["-"] * 4
    assert "relMSE epsilon 0.01" in both.notes[0]


def test_guiding_table_pairs_the_thesis_sizes_with_our_budgets():
    budgets = [{"spp": 8, "seconds": 2.0, "relmse": 0.1, "pt_seconds": 1.0, "pt_relmse": 0.2}]
    table = guiding_table("6.3", budgets, resolution=(32, 24), subject="courtyard")
    thesis = thesis_guiding_times("6.3")
    first = next(iter(thesis))
    assert table.rows[0][0] == f"{first}x{first} / 32x24"
    assert table.rows[0][1] == [str(thesis[first][0]), "8", str(thesis[first][1]), "2.000", str(thesis[first][2]),
                                "1.000", f"{thesis[first][1] / thesis[first][2]:.2f}", "2.00", "0.1 / 0.2"]
    assert len(table.rows) == len(thesis) and table.rows[-1][1][1] == "-"
    assert table.caption.startswith("Table 6.3: Execution times for the San Miguel scene (ours: courtyard;")
    with pytest.raises(ValueError, match="the importance-sampling tables are 6.2, 6.3; got '8.1'"):
        thesis_guiding_times("8.1")
    with pytest.raises(ValueError, match="the equal-time tables are 8.1, 8.2; got '6.2'"):
        thesis_times("6.2")
