"""A comparison's reports from plain rows (issue 18): no renderer, no `experiments/` import.

`write_comparison_outputs` takes rows, a duck-typed configuration and the
experiment folder, and writes every report file through the folder; the
tables are the same objects in the `.md`, the `.csv` and the page.
"""

import csv
import io
import json
import re
from types import SimpleNamespace

import numpy as np
import pytest

from sparselt.report.comparison import (
    COLUMN_ORDER,
    RESULT_COLUMNS,
    THESIS_TABLES,
    equal_time_table,
    results_csv,
    results_table,
    table_6,
    table_8,
    write_comparison_outputs,
)
from sparselt.storage.folder import MANIFEST_FILE, ExperimentFolder

SHAPE = (16, 16, 4, 4)


def _config(kind="dof", methods=("pt", "cosamp")):
    return SimpleNamespace(kind=kind, shape=SHAPE, output_resolution=(16, 16), spps=(40, 81), methods=methods)


FAMILIES = {"pt": "path tracing", "cosamp": "cosamp", "guided-sft": "guided"}


def _methods(names=("pt", "cosamp", "guided-sft"), **families):
    """Method records as compare.json holds them: roles and options."""
    return {name: {"baseline": name == "pt", "family": families.get(name, FAMILIES.get(name, "other")),
                   "thesis_procedure": False, "options": {"map_spp": 16} if name == "guided-sft" else {},
                   "source": "test", "description": name} for name in names}


def _rows(methods=("pt", "cosamp"), spps=(40, 81), seeds=(1, 2)):
    rows = []
    for method in methods:
        for spp in spps:
            for seed in seeds:
                seconds = spp / 40 * (1.0 if method == "pt" else 1.5)
                rows.append({"method": method, "spp": spp, "seed": seed, "seconds_total": seconds,
                             "seconds_sampling": seconds / 2, "seconds_reconstruction": seconds / 4,
                             "seconds_integration": seconds / 8, "seconds_other": seconds / 8,
                             "path_samples": 256 * spp, "ssim": 0.5 + spp / 400, "relmse": 1.0 / spp,
                             "luminance_ratio": 1.0, "contrast_ratio": 1.0, "relmse_pt_equal_time": "",
                             "ssim_pt_equal_time": "", "note": "a, \"b\""})
    for row in rows:
        if row["method"] != "pt" and row["spp"] == 40:
            row["relmse_pt_equal_time"], row["ssim_pt_equal_time"] = 0.02, 0.6
    return rows


def _summary(rows, baseline="pt"):
    """The equal-time protocol's records of the rows (the report is a sink; the protocol lives in experiments/)."""
    from sparselt.experiments.equal_time import add_equal_time_columns, summarize

    return summarize(rows, add_equal_time_columns(rows, baseline=baseline), baseline=baseline)


def _write(tmp_path, rows, config, scene="dof-sculptures"):
    folder = ExperimentFolder(tmp_path / "c", kind="compare-report-test", identity={"scene": scene})
    folder.inspect()
    rng = np.random.default_rng(0)
    images = {(row["method"], row["spp"], row["seed"]): rng.random((16, 16, 3)).astype(np.float32) for row in rows}
    with folder.open():
        written = write_comparison_outputs(folder, rows, rng.random((16, 16, 3)), config, scene, epsilon=0.01,
                                           methods=_methods(config.methods), summary=_summary(rows),
                                           image_of=lambda row: images[row["method"], row["spp"], row["seed"]],
                                           provenance={"versions": {"numpy": np.__version__}, "git": None})
        folder.complete()
    return folder, written


def test_every_report_file_goes_through_the_folder(tmp_path):
    folder, written = _write(tmp_path, _rows(), _config())
    manifest = json.loads((tmp_path / "c" / MANIFEST_FILE).read_text())
    for name in ("results.csv", "quality_vs_time.png", "image_grid.png", "crop_grid.png", "table_8.md", "table_8.csv",
                 "equal_time.md", "equal_time.csv", "index.html"):
        assert name in written and name in manifest["files"], name
        assert (tmp_path / "c" / name).stat().st_size > 0, name
    assert "table_6.md" not in written  # no guided method ran
    page = (tmp_path / "c" / "index.html").read_text()
    assert "has no equal-time PT value (PT" in page and "at 81 spp" in page  # 81 spp is beyond PT's ladder
    assert re.search(r"cosamp (wins|loses|is within noise) at 40 spp \(relMSE [0-9.]+x \[", page)
    for name in ("summary.csv", "results.csv"):
        assert name in written and f'href="{name}"' in page
    assert 'href="table_8.csv"' in page and 'src="image_grid.png"' in page


def test_results_csv_puts_the_column_order_first_and_quotes_through_csv(tmp_path):
    rows = _rows()
    parsed = list(csv.reader(io.StringIO(results_csv(rows))))
    assert tuple(parsed[0][:len(COLUMN_ORDER)]) == COLUMN_ORDER and parsed[0][len(COLUMN_ORDER):] == ["note"]
    assert parsed[1][-1] == 'a, "b"' and len(parsed) == len(rows) + 1
    custom = list(csv.reader(io.StringIO(results_csv(rows, columns=("seed", "method")))))
    assert custom[0][:2] == ["seed", "method"] and set(custom[0]) == {key for row in rows for key in row}
    assert tuple(COLUMN_ORDER[:len(RESULT_COLUMNS)]) == RESULT_COLUMNS


def test_table_8_puts_the_thesis_beside_cosamp_at_depth_of_field_only():
    table = table_8(_rows(), "dof-sculptures", _config(), methods=_methods())
    thesis = THESIS_TABLES["dof-sculptures"][2]
    assert [table.columns[index] for index in table.thesis_columns] == [
        "thesis Total", "thesis Sampling", "thesis CoSaMP", "thesis Integration"]
    by_row = {(label, cells[0]): cells for label, cells in table.rows}
    assert by_row["cosamp", "40"][-4:] == [f"{value:g}" for value in thesis[40]]
    assert by_row["pt", "40"][-4:] == ["-"] * 4
    # Every method's reconstruction phase, not only CoSaMP's (an SFT-guided method's is its map's time).
    assert "| method | SPP | Total | Sampling | Reconstruction | Integration |" in table.markdown()
    assert "CoSaMP" not in table.columns[:table.thesis_columns[0]]
    assert not table_8(_rows(), "dof-sculptures", _config(kind="indirect"), methods=_methods()).thesis_columns
    assert not table_8(_rows(), "cornell-box", _config(), methods=_methods()).thesis_columns


def test_equal_time_table_compares_only_where_pt_reaches_the_time():
    rows = _rows()
    cells = {(label, cells[0]): cells for label, cells in equal_time_table(_summary(rows), methods=_methods()).rows}
    assert set(cells) == {("cosamp", "40"), ("cosamp", "81")}  # PT itself is not compared with PT
    # cosamp at 40 spp takes 1.5 s, inside PT's ladder (1 s to 2.03 s); at 81 spp 3.04 s, beyond it.
    assert cells["cosamp", "40"][4] != "-" and cells["cosamp", "40"][6] in ("wins", "loses", "within noise")
    assert cells["cosamp", "81"][4] == "-" and cells["cosamp", "81"][6] == "no PT value"


def test_table_6_for_guided_methods_with_the_thesis_beside(tmp_path):
    rows = _rows(methods=("pt", "guided-sft"))
    ours, thesis = table_6(rows, "cornell-caustics", _config(kind="path", methods=("pt", "guided-sft")),
                           methods=_methods())
    assert [label for label, _ in ours.rows] == ["guided-sft", "guided-sft"]
    assert [cells[2] for _, cells in ours.rows] == ["16", "16"]  # the method's own resolved map_spp
    # Thesis Table 6.2 beside our budgets, row i pairing its i-th image size with our i-th spp (as reproduce shows it).
    assert thesis.kinds == ["thesis", "ours"] * 4 + ["ours"]
    label, cells = thesis.rows[0]
    pt_40 = [row for row in rows if row["method"] == "pt" and row["spp"] == 40]
    guided_40 = [row for row in rows if row["method"] == "guided-sft" and row["spp"] == 40]
    assert label == "1000x1000 / 16x16" and cells[0::2][:3] == ["489", "238", "199"] and cells[1] == "40"
    assert cells[3] == f"{np.mean([row['seconds_total'] for row in guided_40]):.3f}"
    assert cells[5] == f"{np.mean([row['seconds_total'] for row in pt_40]):.3f}"
    label, cells = thesis.rows[2]  # the thesis's third size; we ran two budgets
    assert label == "4000x4000 / -" and cells[0] == "124" and [cells[index] for index in (1, 3, 5, 7, 8)] == ["-"] * 5
    assert table_6(_rows(), "cornell-caustics", _config(), methods=_methods()) == []
    _, written = _write(tmp_path, rows, _config(kind="path", methods=("pt", "guided-sft")), scene="cornell-caustics")
    assert {"table_6.md", "table_6.csv"} <= set(written)
    assert "Table 6.2: Execution times for the Cornell Box scene (ours: cornell-caustics = Cornell Box, guided-sft" in (
        tmp_path / "c" / "table_6.md").read_text()


def test_results_table_prints_a_dash_where_pt_does_not_reach():
    text = results_table(_rows())
    lines = text.splitlines()
    assert lines[0].startswith("method") and len(lines) == 2 + 8
    assert lines[-1].rstrip().endswith("-") and "0.02" in text


def test_writing_outside_an_open_folder_is_refused(tmp_path):
    folder = ExperimentFolder(tmp_path / "c", kind="compare-report-test", identity={})
    with pytest.raises(RuntimeError, match="outside 'with folder.open"):
        write_comparison_outputs(folder, [], np.zeros((16, 16, 3)), _config(), "cornell-box", epsilon=0.01,
                                 methods={}, summary=[], image_of=None, provenance={})


def test_reports_choose_rows_by_role_not_by_name():
    """A baseline, a guided method and a CoSaMP method with names that match none of the old prefixes."""
    names = ("reference-tracer", "adaptive-guide", "my-sparse")
    rows = _rows(methods=names)
    methods = _methods(names, **{"adaptive-guide": "guided", "my-sparse": "cosamp"})
    methods["reference-tracer"]["baseline"] = True
    methods["adaptive-guide"]["options"] = {"map_spp": 7}
    by_row = {(label, cells[0]): cells for label, cells in table_8(rows, "dof-sculptures", _config(),
                                                                    methods=methods).rows}
    thesis = THESIS_TABLES["dof-sculptures"][2]
    assert by_row["my-sparse", "40"][-4:] == [f"{value:g}" for value in thesis[40]]
    assert by_row["adaptive-guide", "40"][-4:] == ["-"] * 4
    compared = {label for label, _ in equal_time_table(_summary(rows, "reference-tracer"), methods=methods).rows}
    assert compared == {"adaptive-guide", "my-sparse"}  # the baseline is not compared with itself
    ours, _ = table_6(rows, "cornell-caustics", _config(kind="path"), methods=methods)
    assert {label for label, _ in ours.rows} == {"adaptive-guide"}
    assert all(cells[2] == "7" and cells[4] != "-" for _, cells in ours.rows)  # its map_spp; the baseline's time
    # A method named like the old prefixes but of another family gets no thesis column.
    renamed = _rows(methods=("pt", "cosamp-lookalike"))
    table = table_8(renamed, "dof-sculptures", _config(), methods=_methods(("pt", "cosamp-lookalike")))
    assert all(cells[-4:] == ["-"] * 4 for _, cells in table.rows)


# ------------------------------------------------------------------------------ the figures


def _matched(count=9, height=64, width=64):
    from sparselt.report.comparison_figures import matched_pictures

    names = ("pt", "samples-mean", "cosamp", "cosamp-thesis", "bilateral", "cosamp-bilateral", "oidn",
             "guided-cosamp", "guided-bilateral")[:count]
    rows = [{"method": name, "spp": 40, "seed": 1, "seconds_total": 0.06 * 1.9 ** index, "ssim": 0.812,
             "relmse": 0.0123456, "luminance_ratio": 0.98} for index, name in enumerate(names)]
    rng = np.random.default_rng(3)
    images = {row["method"]: rng.random((height, width, 3)) for row in rows}
    return matched_pictures(rows, rng.random((height, width, 3)), lambda row: images[row["method"]])


def _overlaps(first, second):
    return not (first.x1 <= second.x0 or second.x1 <= first.x0 or first.y1 <= second.y0 or second.y1 <= first.y0)


@pytest.mark.parametrize("count, height, width", [(9, 64, 64), (9, 16, 24), (2, 64, 64), (1, 40, 16)],
                         ids=["ten-panels", "wide-images", "three-panels", "tall-images"])
def test_grid_titles_overlap_no_image_and_no_other_text(count, height, width):
    """Multi-line titles of every row stay above their own images (the second row overprinted the first)."""
    from sparselt.report.comparison_figures import crop_grid_figure, image_grid_figure
    from sparselt.report.plotting import pyplot

    matched = _matched(count, height, width)
    for make in (image_grid_figure, crop_grid_figure):
        figure = make(*matched)
        renderer = figure.canvas.get_renderer()
        axes = [axis for axis in figure.axes if axis.get_visible()]
        texts = ([axis.title for axis in axes if axis.get_title()] + [axis.yaxis.label for axis in axes
                                                                       if axis.get_ylabel()] + list(figure.texts))
        assert len(texts) > len(matched[0])  # a title per panel and the heading
        for text in texts:
            box = text.get_window_extent(renderer)
            for axis in axes:
                assert not _overlaps(box, axis.get_window_extent(renderer)), (make.__name__, text.get_text())
            for other in texts:
                if other is not text:
                    assert not _overlaps(box, other.get_window_extent(renderer)), (text.get_text(), other.get_text())
            assert text.get_fontsize() >= 10, (make.__name__, text.get_text())
        pyplot().close(figure)


def test_the_heading_states_the_target_and_the_range_of_panel_times():
    from sparselt.report.comparison_figures import image_grid_figure, matched_time_text
    from sparselt.report.plotting import pyplot

    matched, target, pictures = _matched()
    seconds = [row["seconds_total"] for row in matched]
    assert target == pytest.approx(max(seconds))  # one run per method: the slowest method's shortest run
    text = matched_time_text(matched, target)
    assert text == f"each method at its run closest to {target:.2f} s (panels 0.06-{target:.2f} s)"
    figure = image_grid_figure(matched, target, pictures)
    assert [label.get_text() for label in figure.texts] == [text]
    pyplot().close(figure)


def test_the_quality_legend_is_legible():
    from sparselt.report.comparison_figures import quality_figure
    from sparselt.report.plotting import pyplot

    figure = quality_figure(_rows(), "dof-sculptures", 0.01)
    assert figure.legends and all(text.get_fontsize() >= 9 for text in figure.legends[0].get_texts())
    pyplot().close(figure)
