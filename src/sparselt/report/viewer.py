"""An interactive image viewer for report pages: comparison slider, zoom and pan, exposure, error view.

One viewer shows one scene: a reference image and every method's image at
matched time (8-bit sRGB PNG files next to the page, all the same size),
each method with a false-colour per-pixel error PNG written by Python. Two
layers are shown one over the other, split by a draggable divider; both
zoom and pan together. The page works from ``file://`` with no network: the
styles and the script are inlined once per page (:func:`viewer_assets`),
and each viewer (:func:`viewer_html`) is a ``.sparselt-viewer`` element whose
data (labels, paths, captions) travels in a ``<script
type="application/json">`` block.

The script (``viewer.js``) defines one global, ``window.sparseltViewer``
(``init(element)``), initialises every ``.sparselt-viewer`` on
``DOMContentLoaded``, and mirrors each viewer's state on its element for
headless tests: ``data-slider`` (divider position, 0 to 1), ``data-view``
(``"image"`` or ``"error"``), ``data-zoom``, ``data-pan-x`` and
``data-pan-y`` (the image's offset as fractions of the stage), ``data-exposure``
(stops), ``data-left`` and ``data-right`` (labels), ``data-ready``
(``"true"`` once every image and error image has loaded or failed) and
``data-broken`` (the paths that failed, space separated).
"""

from __future__ import annotations

import html
import json
import os
import re
from collections.abc import Mapping, Sequence
from functools import lru_cache
from importlib import resources

#: The keys of a method's entry (``label`` and ``image`` required) and of the reference.
ENTRY_KEYS = ("label", "image", "error", "caption")
REFERENCE_KEYS = ("label", "image", "caption")
#: The exposure control: a display gain of ``2 ** stops`` in linear light, in these limits and steps.
EXPOSURE_STOPS = (-4.0, 4.0)
EXPOSURE_STEP = 0.5

_IDENTIFIER = re.compile(r"[A-Za-z][A-Za-z0-9_-]*\Z")
_SCHEME = re.compile(r"[A-Za-z][A-Za-z0-9+.-]*:")

EXPOSURE_NOTE = ("Exposure is a display gain of 2^stops in linear light on the tone-mapped 8-bit images, not a "
                 "re-exposure of the renders: highlights clipped by the tone mapping stay clipped and dark regions "
                 "show 8-bit steps. Error view shows the error images as written, without the gain.")
HELP_NOTE = ("Drag the divider (or, when not zoomed, anywhere on the image) or use the arrow keys to compare; wheel, "
             "+ and - zoom about the pointer, drag pans, double-click or 0 resets.")


@lru_cache(maxsize=1)
def viewer_assets():
    """The viewer's ``<style>`` and ``<script>`` blocks, to put once in a page's ``<head>`` (or body).

    Returns
    -------
    str
        ``viewer.css`` and ``viewer.js`` (package data of :mod:`sparselt.report`) inlined, so the page
        needs no other file and no network.

    Notes
    -----
    The script is idempotent: included twice, it defines ``window.sparseltViewer`` once and initialises each
    viewer once.
    """
    folder = resources.files("sparselt.report")
    style = folder.joinpath("viewer.css").read_text(encoding="utf-8")
    script = folder.joinpath("viewer.js").read_text(encoding="utf-8")
    if "</" in style or "</script" in script.lower():
        raise RuntimeError("viewer.css or viewer.js contains '</', which would end its inline block early")
    return f"<style>\n{style}</style>\n<script>\n{script}</script>\n"


def viewer_html(entries, *, reference, identifier, legend=""):
    """One viewer's markup: the reference and the methods' images, a comparison slider, zoom, exposure, error view.

    Parameters
    ----------
    entries : sequence of dict
        One per method, in the order of the selectors: ``{"label": str, "image": str, "error": str or None,
        "caption": str}``. ``label`` (unique, not empty) and ``image`` are required; ``error`` is the
        false-colour error image (missing or None: the error view shows a placeholder); ``caption`` defaults
        to ``""`` (e.g. ``"16 spp, 0.31 s, relMSE 0.012"``). Paths are relative to the page.
    reference : dict
        ``{"label": str, "image": str, "caption": str}`` (``caption`` optional); it has no error image.
    identifier : str
        The viewer element's ``id``, unique on the page: a letter, then letters, digits, ``-`` or ``_``.
    legend : str, optional
        What the error images' colours mean (e.g. ``"relative squared error, log scale 1e-4 to 1"``); shown
        in error view.

    Returns
    -------
    str
        A ``<div class="sparselt-viewer">``; the page needs :func:`viewer_assets` once.

    Raises
    ------
    TypeError
        ``entries`` is not a list of dicts, ``reference`` is not a dict, or a label, path, caption or the
        legend is not a string.
    ValueError
        No entries; an entry or the reference lacks ``label`` or ``image``, has an unknown key, an empty
        label, a label used twice, or an absolute path or URL; a bad ``identifier``.

    Notes
    -----
    The left layer starts as the first method, the right one as the reference, the divider in the middle.
    Every text is escaped here: labels and captions go into the markup through :func:`html.escape` and into
    the JSON block with ``<``, ``>`` and ``&`` written as ``\\u003c``, ``\\u003e``, ``\\u0026``, so a label
    such as ``</script>`` stays text.
    """
    if not isinstance(identifier, str) or not _IDENTIFIER.match(identifier):
        raise ValueError(f"identifier must be a letter followed by letters, digits, '-' or '_', got {identifier!r}")
    if not isinstance(legend, str):
        raise TypeError(f"legend must be a string, got {type(legend).__name__}")
    images = [_checked(reference, "reference", REFERENCE_KEYS)]
    if isinstance(entries, (str, bytes, Mapping)) or not isinstance(entries, Sequence):
        raise TypeError(f"entries must be a list of dicts, got {type(entries).__name__}")
    if not entries:
        raise ValueError("entries is empty: a viewer needs at least one method's image")
    images += [_checked(entry, f"entry {index}", ENTRY_KEYS) for index, entry in enumerate(entries)]
    seen = {}
    for index, image in enumerate(images):
        name = "the reference" if index == 0 else f"entry {index - 1}"
        if image["label"] in seen:
            raise ValueError(f"{name} has the label {image['label']!r} of {seen[image['label']]}: labels must "
                             "be unique within a viewer")
        seen[image["label"]] = name
    left, right = 1, 0
    data = {"images": images, "left": left, "right": right, "legend": legend,
            "filter": f"{identifier}-exposure"}
    payload = (json.dumps(data, ensure_ascii=True, separators=(",", ":"))
               .replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026"))

    def options(selected):
        names = [image["label"] for image in images]
        if names[0] != "reference":
            names[0] += " (reference)"
        return "".join(f"<option value=\"{index}\"{' selected' if index == selected else ''}>{_escape(name)}</option>"
                       for index, name in enumerate(names))

    def layer(side, index):
        return (f"<div class=\"sparselt-viewer-layer sparselt-viewer-layer-{side}\" data-role=\"{side}-layer\""
                + (" style=\"clip-path: inset(0 50% 0 0)\"" if side == "left" else "") + ">"
                f"<img src=\"{_escape(images[index]['image'])}\" alt=\"{_escape(images[index]['label'])}\" "
                f"draggable=\"false\" data-role=\"{side}-image\">"
                f"<span class=\"sparselt-viewer-placeholder\" data-role=\"{side}-placeholder\">no error image</span>"
                "</div>")

    def caption(side, index):
        text = images[index]["caption"]
        return (f"<p class=\"sparselt-viewer-caption-{side}\" data-role=\"{side}-caption\">"
                f"<strong>{_escape(images[index]['label'])}</strong>{': ' + _escape(text) if text else ''}</p>")

    low, high = EXPOSURE_STOPS
    slope = "<feFunc{0} type=\"linear\" slope=\"1\" data-role=\"exposure-gain\"/>"
    return "".join([
        f"<div class=\"sparselt-viewer\" id=\"{identifier}\" data-ready=\"false\">",
        f"<script type=\"application/json\" data-role=\"data\">{payload}</script>",
        "<svg class=\"sparselt-viewer-filters\" aria-hidden=\"true\" focusable=\"false\">"
        f"<filter id=\"{identifier}-exposure\" color-interpolation-filters=\"linearRGB\"><feComponentTransfer>"
        + "".join(slope.format(channel) for channel in "RGB") + "</feComponentTransfer></filter></svg>",
        "<div class=\"sparselt-viewer-controls\">",
        f"<label>left <select data-role=\"left-select\">{options(left)}</select></label>",
        f"<label>right <select data-role=\"right-select\">{options(right)}</select></label>",
        ("<label title=\"show each method's per-pixel error image instead of its image\">"
         "<input type=\"checkbox\" data-role=\"error-toggle\"> error view</label>"),
        ("<label title=\"display gain on the tone-mapped 8-bit images, in stops (linear light)\">exposure "
         f"<input type=\"range\" min=\"{low:g}\" max=\"{high:g}\" step=\"{EXPOSURE_STEP:g}\" value=\"0\" "
         "data-role=\"exposure\" aria-label=\"exposure in stops (display gain)\"> "
         "<output data-role=\"exposure-value\">+0.0 stops</output></label>"),
        ("<span><button type=\"button\" data-role=\"zoom-in\" title=\"zoom in (+)\">+</button> "
         "<button type=\"button\" data-role=\"zoom-out\" title=\"zoom out (-)\">\u2212</button> "
         "<button type=\"button\" data-role=\"reset\" title=\"reset zoom and pan (0, double-click)\">reset</button> "
         "<output data-role=\"zoom-value\">\u00d71</output></span>"),
        "</div>",
        ("<div class=\"sparselt-viewer-stage\" data-role=\"stage\" tabindex=\"0\" "
         "aria-label=\"image comparison: arrow keys move the divider, + and - zoom, 0 resets\">"),
        layer("right", right), layer("left", left),
        ("<div class=\"sparselt-viewer-divider\" data-role=\"divider\" role=\"slider\" tabindex=\"0\" "
         "aria-label=\"comparison divider\" aria-valuemin=\"0\" aria-valuemax=\"100\" aria-valuenow=\"50\"></div>"),
        (f"<span class=\"sparselt-viewer-tag sparselt-viewer-tag-left\" data-role=\"left-tag\">"
         f"{_escape(images[left]['label'])}</span>"),
        (f"<span class=\"sparselt-viewer-tag sparselt-viewer-tag-right\" data-role=\"right-tag\">"
         f"{_escape(images[right]['label'])}</span>"),
        "</div>",
        (f"<div class=\"sparselt-viewer-captions\" data-role=\"captions\">{caption('left', left)}"
         f"{caption('right', right)}</div>"),
        f"<p class=\"sparselt-viewer-legend\" data-role=\"legend\" hidden>Error view: {_escape(legend)}</p>"
        if legend else "",
        "<p class=\"sparselt-viewer-warning\" data-role=\"warning\" hidden></p>",
        f"<p class=\"sparselt-viewer-note\">{_escape(HELP_NOTE)} {_escape(EXPOSURE_NOTE)}</p>",
        "</div>",
    ])


def viewer_page_html(title, viewers, *, note=""):
    """A standalone page of viewers, one after another, each under its heading.

    Parameters
    ----------
    title : str
        The page's title and first heading.
    viewers : sequence of dict
        Each :func:`viewer_html`'s keyword arguments (``entries``, ``reference``, ``legend``, and optionally
        ``identifier``, by default ``"viewer-N"``) plus an optional ``title``, the viewer's heading.
    note : str, optional
        A paragraph under the title.

    Returns
    -------
    str
        The page, with :func:`viewer_assets` in its ``<head>``.

    Raises
    ------
    TypeError
        A viewer is not a dict, or as :func:`viewer_html`.
    ValueError
        As :func:`viewer_html`; two viewers with one identifier; a viewer with an unknown key.
    """
    known = {"title", "entries", "reference", "identifier", "legend"}
    parts, identifiers = [], set()
    for number, viewer in enumerate(viewers):
        if not isinstance(viewer, Mapping):
            raise TypeError(f"viewer {number} must be a dict of viewer_html's arguments, got {type(viewer).__name__}")
        unknown = sorted(set(viewer) - known)
        if unknown:
            raise ValueError(f"viewer {number} has unknown keys {unknown}; allowed: {sorted(known)}")
        identifier = viewer.get("identifier", f"viewer-{number}")
        if identifier in identifiers:
            raise ValueError(f"viewer {number} repeats the identifier {identifier!r}: identifiers must be unique")
        identifiers.add(identifier)
        if viewer.get("title"):
            parts.append(f"<h2>{_escape(viewer['title'])}</h2>")
        parts.append(viewer_html(viewer.get("entries"), reference=viewer.get("reference"), identifier=identifier,
                                 legend=viewer.get("legend", "")))
    return "\n".join(["<!DOCTYPE html>", "<html lang=\"en\"><head><meta charset=\"utf-8\">",
                      f"<title>{_escape(title)}</title>",
                      ("<style>body { font-family: -apple-system, \"Segoe UI\", Helvetica, Arial, sans-serif; "
                       "margin: 2em auto; max-width: 70em; padding: 0 1.5em; color: #222; }</style>"),
                      viewer_assets(), "</head><body>", f"<h1>{_escape(title)}</h1>",
                      f"<p>{_escape(note)}</p>" if note else "", *parts, "</body></html>", ""])


def write_viewer_page(path, title, viewers, *, note=""):
    """Write a standalone page of viewers (:func:`viewer_page_html`) atomically; return ``path``.

    Parameters
    ----------
    path : str
        The page; every image path is relative to its folder.
    title : str
    viewers : sequence of dict
        As :func:`viewer_page_html`.
    note : str, optional
        A paragraph under the title.

    Returns
    -------
    str
        ``path``.

    Raises
    ------
    TypeError
        As :func:`viewer_page_html`.
    ValueError
        As :func:`viewer_page_html`, or an image or error image that does not exist next to the page.
    """
    from ..provenance import atomic_write_bytes

    folder = os.path.dirname(os.path.abspath(path))
    text = viewer_page_html(title, viewers, note=note)
    for number, viewer in enumerate(viewers):
        for image in [viewer["reference"], *viewer["entries"]]:
            for key in ("image", "error"):
                target = image.get(key)
                if target is not None and not os.path.exists(os.path.join(folder, target)):
                    raise ValueError(f"viewer {number}: {image['label']!r}'s {key} {target!r} does not exist in "
                                     f"{folder!r}")
    atomic_write_bytes(path, text.encode("utf-8"))
    return path


def _escape(text):
    return html.escape(str(text), quote=True)


def _checked(entry, name, keys):
    """``entry`` with every key of ``keys`` (absent optional ones as ``""`` or None), checked."""
    if not isinstance(entry, Mapping):
        raise TypeError(f"{name} must be a dict with keys {list(keys)}, got {type(entry).__name__}")
    unknown = sorted(set(entry) - set(keys), key=str)
    if unknown:
        raise ValueError(f"{name} has unknown keys {unknown}; allowed: {list(keys)}")
    missing = [key for key in ("label", "image") if key not in entry]
    if missing:
        raise ValueError(f"{name} lacks {missing}: label and image are required")
    label = entry["label"]
    if not isinstance(label, str):
        raise TypeError(f"{name}'s label must be a string, got {type(label).__name__}")
    if not label.strip():
        raise ValueError(f"{name}'s label is empty")
    checked = {"label": label}
    for key in ("image", "error") if "error" in keys else ("image",):
        path = entry.get(key)
        if path is None and key == "error":
            checked[key] = None
            continue
        if not isinstance(path, str):
            raise TypeError(f"{name} ({label!r}): {key} must be a path string, got {type(path).__name__}")
        if not path or os.path.isabs(path) or path.startswith(("/", "\\")) or _SCHEME.match(path):
            raise ValueError(f"{name} ({label!r}): {key} must be a path relative to the page, got {path!r}")
        checked[key] = path
    caption = entry.get("caption", "")
    if caption is None:
        caption = ""
    if not isinstance(caption, str):
        raise TypeError(f"{name} ({label!r}): caption must be a string, got {type(caption).__name__}")
    checked["caption"] = caption
    return checked
