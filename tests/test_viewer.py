"""The report's image viewer (:mod:`sparselt.report.viewer`): its markup and validation in Python, and its
behaviour in headless chromium, driven by real DOM events (pointer drags, keys, wheel, change and input)."""

import html
import json
import os
import re
import subprocess
from html.parser import HTMLParser

import numpy as np
import pytest
from matplotlib import image as matplotlib_image
from test_reproduce import chromium, rendered_dom  # noqa: F401  (the headless-browser fixture)

from sparselt.images import srgb_tonemap
from sparselt.report.viewer import viewer_assets, viewer_html, viewer_page_html, write_viewer_page

WIDTH, HEIGHT = 16, 12
AWKWARD_LABEL = "</script><b onclick=\"x()\">it's & \"quoted\"</b>"
VARIANT_LABEL = "aaf-dof:width_scale=0.5"


def _write_png(path, value):
    """A flat 8-bit RGB PNG of ``value`` (0-255; a triple for a colour)."""
    pixels = np.empty((HEIGHT, WIDTH, 3), dtype=np.uint8)
    pixels[...] = value
    matplotlib_image.imsave(path, pixels)


def _entries():
    return [{"label": "pt", "image": "pt.png", "error": "pt_error.png", "caption": "pt 16 spp, 0.31 s"},
            {"label": VARIANT_LABEL, "image": "aaf.png", "error": "aaf_error.png", "caption": "relMSE 0.012"}]


REFERENCE = {"label": "reference", "image": "reference.png", "caption": "4096 spp"}


def _json_block(markup):
    return json.loads(re.search(r'<script type="application/json" data-role="data">(.*?)</script>', markup,
                                re.DOTALL).group(1))


class _Viewers(HTMLParser):
    """The attributes of every ``.sparselt-viewer`` element and the option texts of its selectors."""

    def __init__(self):
        super().__init__()
        self.viewers, self.options, self._option = [], [], False

    def handle_starttag(self, tag, attributes):
        attributes = dict(attributes)
        if "sparselt-viewer" in (attributes.get("class") or "").split():
            self.viewers.append(attributes)
        self._option = tag == "option"

    def handle_endtag(self, tag):
        self._option = False

    def handle_data(self, data):
        if self._option:
            self.options.append(data)


def _parsed(markup):
    parser = _Viewers()
    parser.feed(markup)
    return parser


# Python: markup, escaping and validation.

def test_labels_and_captions_are_escaped_in_the_markup_and_the_json_block():
    entries = [{"label": AWKWARD_LABEL, "image": "a.png", "error": "a_error.png", "caption": "</script> & <i>"},
               {"label": VARIANT_LABEL, "image": "b.png", "error": None}]
    markup = viewer_html(entries, reference=REFERENCE, identifier="scene-1", legend="log </p> scale")
    assert markup.count("</script>") == 1  # the data block's own end: no label closes it early
    assert "<b onclick" not in markup and "<i>" not in markup and "</p> scale" not in markup
    data = _json_block(markup)
    assert [image["label"] for image in data["images"]] == ["reference", AWKWARD_LABEL, VARIANT_LABEL]
    assert data["images"][1]["caption"] == "</script> & <i>" and data["images"][2]["error"] is None
    assert data["legend"] == "log </p> scale" and (data["left"], data["right"]) == (1, 0)
    parsed = _parsed(markup)
    assert parsed.viewers[0]["id"] == "scene-1"
    assert parsed.options == ["reference", AWKWARD_LABEL, VARIANT_LABEL] * 2


def test_the_assets_inline_the_packaged_style_and_script_once():
    assets = viewer_assets()
    assert assets.count("<style>") == 1 and assets.count("<script>") == 1
    assert assets.count("</style>") == 1 and assets.count("</script>") == 1
    assert "window.sparseltViewer" in assets and ".sparselt-viewer-stage" in assets
    assert "http:" not in assets and "https:" not in assets  # no network


@pytest.mark.parametrize("entries, reference, identifier, message", [
    ([], REFERENCE, "v", "entries is empty"),
    ([{"image": "a.png"}], REFERENCE, "v", r"entry 0 lacks \['label'\]"),
    ([{"label": "a"}], REFERENCE, "v", r"entry 0 lacks \['image'\]"),
    ([{"label": "a", "image": "a.png", "errror": "e.png"}], REFERENCE, "v", r"entry 0 has unknown keys \['errror'\]"),
    ([{"label": "a", "image": "a.png"}, {"label": " ", "image": "b.png"}], REFERENCE, "v", "entry 1's label is empty"),
    ([{"label": "a", "image": "a.png"}, {"label": "a", "image": "b.png"}], REFERENCE, "v",
     "entry 1 has the label 'a' of entry 0"),
    ([{"label": "reference", "image": "a.png"}], REFERENCE, "v", "entry 0 has the label 'reference' of the reference"),
    ([{"label": "a", "image": "/tmp/a.png"}], REFERENCE, "v", r"entry 0 \('a'\): image must be a path relative"),
    ([{"label": "a", "image": "a.png", "error": "https://example.org/e.png"}], REFERENCE, "v",
     r"entry 0 \('a'\): error must be a path relative"),
    ([{"label": "a", "image": "a.png"}], dict(REFERENCE, error="r.png"), "v",
     r"reference has unknown keys \['error'\]"),
    ([{"label": "a", "image": "a.png"}], {"label": "reference"}, "v", r"reference lacks \['image'\]"),
    ([{"label": "a", "image": "a.png"}], REFERENCE, "1st viewer", "identifier must be a letter"),
])
def test_a_bad_entry_is_a_value_error_naming_it(entries, reference, identifier, message):
    with pytest.raises(ValueError, match=message):
        viewer_html(entries, reference=reference, identifier=identifier)


@pytest.mark.parametrize("entries, reference, legend, message", [
    ({"label": "a", "image": "a.png"}, REFERENCE, "", "entries must be a list of dicts"),
    (["a.png"], REFERENCE, "", "entry 0 must be a dict"),
    ([{"label": 3, "image": "a.png"}], REFERENCE, "", "entry 0's label must be a string"),
    ([{"label": "a", "image": "a.png", "caption": 0.5}], REFERENCE, "", r"entry 0 \('a'\): caption must be a string"),
    ([{"label": "a", "image": "a.png"}], "reference.png", "", "reference must be a dict"),
    ([{"label": "a", "image": "a.png"}], REFERENCE, None, "legend must be a string"),
])
def test_a_badly_typed_argument_is_a_type_error_naming_it(entries, reference, legend, message):
    with pytest.raises(TypeError, match=message):
        viewer_html(entries, reference=reference, identifier="v", legend=legend)


def test_a_standalone_page_refuses_missing_files_and_repeated_identifiers(tmp_path):
    for name in ("reference", "pt", "pt_error", "aaf", "aaf_error"):
        _write_png(tmp_path / f"{name}.png", 128)
    viewer = {"title": "scene", "entries": _entries(), "reference": REFERENCE, "legend": "log scale"}
    page = write_viewer_page(str(tmp_path / "index.html"), "viewers", [viewer])
    with open(page, encoding="utf-8") as written:
        assert _parsed(written.read()).viewers[0]["id"] == "viewer-0"
    with pytest.raises(ValueError, match="'pt'.s error 'gone.png' does not exist"):
        write_viewer_page(str(tmp_path / "other.html"), "viewers",
                          [dict(viewer, entries=[dict(_entries()[0], error="gone.png")])])
    with pytest.raises(ValueError, match="viewer 1 repeats the identifier 'viewer-0'"):
        viewer_page_html("viewers", [viewer, dict(viewer, identifier="viewer-0")])
    with pytest.raises(ValueError, match=r"viewer 0 has unknown keys \['legnd'\]"):
        viewer_page_html("viewers", [{"entries": _entries(), "reference": REFERENCE, "legnd": ""}])
    assert not os.path.exists(tmp_path / "other.html")


# The browser: real DOM events on two viewers, then the dumped DOM.

#: Runs in the page after both viewers are ready: drives the first with DOM events, records its state after
#: each step (``body[data-test-log]``), and the second's before and after.
DRIVER = """
<script>
(function () {
  function snapshot(viewer) {
    var record = {};
    ['slider', 'view', 'zoom', 'pan-x', 'pan-y', 'exposure', 'left', 'right', 'ready', 'broken'].forEach(
      function (name) { record[name] = viewer.getAttribute('data-' + name); });
    ['left', 'right'].forEach(function (side) {
      var layer = viewer.querySelector('[data-role="' + side + '-layer"]');
      record[side + '-src'] = viewer.querySelector('[data-role="' + side + '-image"]').getAttribute('src');
      record[side + '-filter'] = layer.style.filter;
      record[side + '-missing'] = layer.classList.contains('sparselt-viewer-missing');
    });
    record.clip = viewer.querySelector('[data-role="left-layer"]').style.clipPath;
    record.gain = viewer.querySelector('[data-role="exposure-gain"]').getAttribute('slope');
    record['exposure-disabled'] = viewer.querySelector('[data-role="exposure"]').disabled;
    record['legend-hidden'] = viewer.querySelector('[data-role="legend"]').hidden;
    record.pixelated = viewer.querySelector('[data-role="stage"]').classList.contains('sparselt-viewer-pixelated');
    record.warning = viewer.querySelector('[data-role="warning"]').textContent;
    return record;
  }
  function at(stage, u, v) {
    var box = stage.getBoundingClientRect();
    return {bubbles: true, cancelable: true, pointerId: 1, isPrimary: true, button: 0, buttons: 1,
            pointerType: 'mouse', clientX: box.left + u * box.width, clientY: box.top + v * box.height};
  }
  function drag(target, stage, from, to) {
    target.dispatchEvent(new PointerEvent('pointerdown', at(stage, from[0], from[1])));
    target.dispatchEvent(new PointerEvent('pointermove', at(stage, to[0], to[1])));
    target.dispatchEvent(new PointerEvent('pointerup', at(stage, to[0], to[1])));
  }
  function drive() {
    var first = document.getElementById('first'), second = document.getElementById('second');
    var stage = first.querySelector('[data-role="stage"]'), divider = first.querySelector('[data-role="divider"]');
    var log = {second_before: snapshot(second), initial: snapshot(first)};
    drag(divider, stage, [0.5, 0.5], [0.25, 0.5]);
    divider.dispatchEvent(new PointerEvent('pointermove', at(stage, 0.9, 0.5)));  /* after pointerup: ignored */
    log.dragged = snapshot(first);
    divider.dispatchEvent(new KeyboardEvent('keydown', {key: 'ArrowLeft', bubbles: true, cancelable: true}));
    log.key = snapshot(first);
    var wheel = at(stage, 0.75, 0.5);
    wheel.deltaY = -300;
    wheel.deltaMode = 0;
    stage.dispatchEvent(new WheelEvent('wheel', wheel));
    log.wheel = snapshot(first);
    drag(stage, stage, [0.5, 0.5], [0.6, 0.6]);
    log.panned = snapshot(first);
    var exposure = first.querySelector('[data-role="exposure"]');
    exposure.value = '1.5';
    exposure.dispatchEvent(new Event('input', {bubbles: true}));
    exposure.dispatchEvent(new Event('change', {bubbles: true}));
    log.exposed = snapshot(first);
    var toggle = first.querySelector('[data-role="error-toggle"]');
    toggle.checked = true;
    toggle.dispatchEvent(new Event('change', {bubbles: true}));
    log.error = snapshot(first);
    var left = first.querySelector('[data-role="left-select"]');
    var right = first.querySelector('[data-role="right-select"]');
    left.value = '2';
    left.dispatchEvent(new Event('change', {bubbles: true}));
    right.value = '1';
    right.dispatchEvent(new Event('change', {bubbles: true}));
    log.selected = snapshot(first);
    stage.dispatchEvent(new MouseEvent('dblclick', at(stage, 0.5, 0.5)));
    toggle.checked = false;
    toggle.dispatchEvent(new Event('change', {bubbles: true}));
    log.reset = snapshot(first);
    log.second_after = snapshot(second);
    log.globals = Object.keys(window).filter(function (name) { return /sparselt/i.test(name); });
    document.body.setAttribute('data-test-log', JSON.stringify(log));
  }
  var tries = 0;
  (function wait() {
    if (document.querySelectorAll('.sparselt-viewer[data-ready="true"]').length === 2) { drive(); }
    else if (++tries < 200) { setTimeout(wait, 20); }
    else { document.body.setAttribute('data-test-log', JSON.stringify({timeout: true})); }
  }());
}());
</script>
"""


@pytest.fixture(scope="module")
def driven(tmp_path_factory, chromium):  # noqa: F811
    """Two viewers on one page (the second with a missing error image), driven by :data:`DRIVER`: the log and
    the dumped DOM."""
    folder = tmp_path_factory.mktemp("viewer")
    for name, value in (("reference", 128), ("pt", 60), ("pt_error", (0, 0, 255)), ("aaf", 200),
                        ("aaf_error", (255, 0, 0)), ("awkward", 30)):
        _write_png(folder / f"{name}.png", value)
    entries = _entries()
    second = [dict(entries[0], error="missing_error.png"),
              {"label": AWKWARD_LABEL, "image": "awkward.png", "error": "aaf_error.png"}]
    text = viewer_page_html("two viewers", [
        {"title": "first", "entries": entries, "reference": REFERENCE, "identifier": "first",
         "legend": "relative squared error, log scale 1e-4 to 1"},
        {"title": "second", "entries": second, "reference": REFERENCE, "identifier": "second", "legend": "x"}])
    page = folder / "index.html"
    page.write_text(text.replace("</body>", DRIVER + "</body>"), encoding="utf-8")
    dom = rendered_dom(chromium, page)
    log = json.loads(html.unescape(re.search(r'<body[^>]*\sdata-test-log="([^"]*)"', dom).group(1)))
    assert "timeout" not in log, "the viewers never became ready"
    return log, dom


def test_both_viewers_become_ready_and_a_missing_image_is_reported(driven):
    log, dom = driven
    first, second = _parsed(dom).viewers
    assert first["data-ready"] == second["data-ready"] == "true"
    assert first["data-broken"] == "" and second["data-broken"] == "missing_error.png"
    assert "Could not load: missing_error.png" in log["second_before"]["warning"]
    assert log["initial"]["warning"] == ""
    assert log["globals"] == ["sparseltViewer"]  # the one namespace object, no other global


def test_the_initial_state_is_the_first_method_left_of_the_reference(driven):
    initial = driven[0]["initial"]
    assert (initial["left"], initial["right"]) == ("pt", "reference")
    assert (initial["left-src"], initial["right-src"]) == ("pt.png", "reference.png")
    assert (initial["slider"], initial["view"], initial["zoom"], initial["exposure"]) == ("0.5", "image", "1", "0")
    assert initial["clip"] == "inset(0px 50% 0px 0px)" and initial["left-filter"] == ""


def test_a_drag_and_an_arrow_key_move_the_divider(driven):
    log = driven[0]
    assert float(log["dragged"]["slider"]) == pytest.approx(0.25, abs=0.01)  # a move after pointerup is ignored
    assert log["dragged"]["clip"] == "inset(0px 75% 0px 0px)"
    assert float(log["key"]["slider"]) == pytest.approx(0.20, abs=0.01)


def test_the_wheel_zooms_about_the_pointer_and_a_drag_pans(driven):
    log = driven[0]
    wheel, panned = log["wheel"], log["panned"]
    zoom = float(wheel["zoom"])
    assert zoom == pytest.approx(2.0)
    # The image point under the pointer (0.75, 0.5 of the stage) stays under it: (u - pan) / zoom == u
    # (to a pixel: a wheel event's clientX and clientY are whole pixels).
    assert (0.75 - float(wheel["pan-x"])) / zoom == pytest.approx(0.75, abs=0.005)
    assert (0.5 - float(wheel["pan-y"])) / zoom == pytest.approx(0.5, abs=0.005)
    assert wheel["pixelated"] and wheel["slider"] == log["key"]["slider"]  # panning is not the divider
    assert float(panned["pan-x"]) == pytest.approx(float(wheel["pan-x"]) + 0.1, abs=0.01)
    assert float(panned["pan-y"]) == pytest.approx(float(wheel["pan-y"]) + 0.1, abs=0.01)
    assert panned["slider"] == log["key"]["slider"]


def test_exposure_is_a_linear_light_gain_on_both_layers_and_off_in_error_view(driven):
    log = driven[0]
    exposed, error = log["exposed"], log["error"]
    assert exposed["exposure"] == "1.5" and float(exposed["gain"]) == pytest.approx(2 ** 1.5, rel=1e-4)
    assert exposed["left-filter"] == exposed["right-filter"] == 'url("#first-exposure")'
    assert error["left-filter"] == error["right-filter"] == "" and error["exposure-disabled"]


def test_error_view_shows_every_method_s_error_image_and_the_legend(driven):
    log = driven[0]
    error, selected, reset = log["error"], log["selected"], log["reset"]
    assert error["view"] == "error" and not error["legend-hidden"] and log["panned"]["legend-hidden"]
    assert error["left-src"] == "pt_error.png" and error["right-missing"] and not error["left-missing"]
    assert (selected["left"], selected["right"]) == (VARIANT_LABEL, "pt")
    assert (selected["left-src"], selected["right-src"]) == ("aaf_error.png", "pt_error.png")
    assert not selected["right-missing"]
    assert (reset["view"], reset["zoom"], reset["pan-x"], reset["pan-y"]) == ("image", "1", "0", "0")
    assert (reset["left-src"], reset["right-src"]) == ("aaf.png", "pt.png")
    assert reset["left-filter"] == 'url("#first-exposure")' and not reset["exposure-disabled"]


def test_the_second_viewer_is_not_touched_by_the_first(driven):
    log = driven[0]
    assert log["second_after"] == log["second_before"]
    assert log["second_before"]["left"] == "pt" and log["second_before"]["zoom"] == "1"


def test_an_awkward_label_survives_the_round_trip_to_the_browser(driven):
    dom = driven[1]
    assert AWKWARD_LABEL in _parsed(dom).options
    assert "<b onclick" not in dom


def _srgb_decode(value):
    return value / 12.92 if value <= 0.04045 else ((value + 0.055) / 1.055) ** 2.4


def test_one_stop_of_exposure_doubles_the_light_on_screen(tmp_path, chromium):  # noqa: F811
    """A screenshot: sRGB 100 at +1 stop shows as the sRGB code of twice its linear value (137), not as
    100 times two (what CSS brightness(2) would show)."""
    for name in ("reference", "pt", "pt_error", "aaf", "aaf_error"):
        _write_png(tmp_path / f"{name}.png", 100)
    setter = ("<script>(function wait() { var v = document.querySelector('.sparselt-viewer');"
              " if (v.getAttribute('data-ready') !== 'true') { setTimeout(wait, 20); return; }"
              " var e = v.querySelector('[data-role=\"exposure\"]'); e.value = '1';"
              " e.dispatchEvent(new Event('input', {bubbles: true})); }());</script>")
    page = tmp_path / "index.html"
    page.write_text(viewer_page_html("exposure", [{"entries": _entries(), "reference": REFERENCE}])
                    .replace("</body>", setter + "</body>"), encoding="utf-8")
    screenshot = tmp_path / "screen.png"
    result = subprocess.run([chromium, "--headless", "--no-sandbox", "--disable-gpu", "--allow-file-access-from-files",
                             "--virtual-time-budget=10000", "--window-size=800,900", f"--screenshot={screenshot}",
                             f"file://{page}"], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr[-2000:]
    pixels = np.round(matplotlib_image.imread(screenshot)[..., :3] * 255).astype(int)
    grey = pixels[(pixels[..., 0] == pixels[..., 1]) & (pixels[..., 1] == pixels[..., 2]) & (pixels[..., 0] < 250)]
    values, counts = np.unique(grey[:, 0], return_counts=True)
    expected = 255 * srgb_tonemap(2 * _srgb_decode(100 / 255))
    assert counts.max() > 480 * 300  # the stage, 480 pixels wide, is the largest grey area
    assert values[counts.argmax()] == pytest.approx(expected, abs=2)


def test_a_viewer_works_inside_a_report_page(tmp_path, chromium):  # noqa: F811
    """:func:`sparselt.report.page_html` with the assets in its head and a viewer as a section's markup: the
    page's own image check and the viewer's agree that everything loaded."""
    from sparselt.report.page import Section, page_html

    for name in ("reference", "pt", "pt_error", "aaf", "aaf_error"):
        _write_png(tmp_path / f"{name}.png", 90)
    section = Section(title="scene", markup=viewer_html(_entries(), reference=REFERENCE, identifier="viewer-0",
                                                        legend="log scale"))
    page = tmp_path / "index.html"
    page.write_text(page_html(str(tmp_path), "report", [section], {}, head=viewer_assets()), encoding="utf-8")
    dom = rendered_dom(chromium, page)
    (viewer,) = _parsed(dom).viewers
    assert 'data-broken-images=""' in dom and re.search(r'data-images="2"', dom)  # the viewer's two layers
    assert (viewer["data-ready"], viewer["data-broken"], viewer["data-left"]) == ("true", "", "pt")
