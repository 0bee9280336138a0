"""scripts/rejudge_experiments.py's note on a re-judged suite's page: under the title, once, linking the tables."""

import importlib.util
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "rejudge_experiments.py"


def _script():
    spec = importlib.util.spec_from_file_location("rejudge_experiments", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_a_suite_page_gets_one_note_under_its_title_however_often_it_is_rejudged(tmp_path):
    script = _script()
    page = tmp_path / "index.html"
    page.write_text("<html><body>\n<h1>sparselt suite: s</h1>\n<table>first judgement</table>\n</body></html>\n")
    script.note_suite_page(page)
    once = page.read_text()
    script.note_suite_page(page)
    assert page.read_text() == once and once.count('id="rejudged"') == 1
    assert once.index("</h1>") < once.index('id="rejudged"') < once.index("<table>")
    assert 'href="aggregate.md"' in once and "first judgement" in once
    script.note_suite_page(tmp_path / "missing.html")  # no page: nothing written
    assert not (tmp_path / "missing.html").exists()
