"""Copy a finished suite (or comparison) folder's report into the repository: tables, pages and PNGs, no npy or EXR.

Usage::

    .venv/bin/python scripts/publish_suite.py out/suite-default docs/experiments/suite-default

What is copied: the suite's ``index.html``, ``suite.csv``, ``aggregate.csv``/``.md``, ``suite.json``,
``speedups.png`` and ``viewer/`` (the matched-time images and error maps the page shows); per scene its
comparison's report files (``index.html``, tables, ``compare.json`` and the figures its page shows). Not
copied: images of every cell (``scenes/*/images/``), cell records and timing repeats, the references'
passes, arrays (``.npy``), EXR files, manifests and locks. The pages keep working: every file they show is
copied (checked).
"""

from __future__ import annotations

import os
import re
import shutil
import sys

SKIPPED_FOLDERS = {"images", "cells", "repeats", "references"}
SKIPPED_SUFFIXES = (".npy", ".exr", ".lock")
SKIPPED_NAMES = {"sparselt-folder.json"}


def publish(source, target):
    """Copy ``source``'s report into ``target`` (created; refused if it holds anything); return the files."""
    finished = any(os.path.isfile(os.path.join(source, name)) for name in ("suite.json", "compare.json"))
    if not finished or not os.path.isfile(os.path.join(source, "index.html")):
        raise SystemExit(f"{source!r} is not a finished suite or comparison folder (no suite.json or compare.json, "
                         "and index.html)")
    if os.path.exists(target) and os.listdir(target):
        raise SystemExit(f"{target!r} is not empty: publish into a new folder")
    copied = []
    for root, folders, files in os.walk(source):
        folders[:] = sorted(name for name in folders if name not in SKIPPED_FOLDERS and not name.startswith("."))
        for name in sorted(files):
            if name in SKIPPED_NAMES or name.endswith(SKIPPED_SUFFIXES) or name.startswith("."):
                continue
            relative = os.path.relpath(os.path.join(root, name), source)
            destination = os.path.join(target, relative)
            os.makedirs(os.path.dirname(destination), exist_ok=True)
            shutil.copy2(os.path.join(root, name), destination)
            copied.append(relative)
    for page in [name for name in copied if name.endswith("index.html")]:
        folder = os.path.dirname(os.path.join(target, page))
        with open(os.path.join(target, page), encoding="utf-8") as handle:
            text = handle.read()
        for reference in re.findall(r'(?:src|href)="([^"#:]+)"', text):
            if not os.path.exists(os.path.join(folder, reference)):
                raise SystemExit(f"{page} shows {reference!r}, which was not copied")
    return copied


if __name__ == "__main__":
    if len(sys.argv) != 3:
        raise SystemExit(__doc__)
    files = publish(sys.argv[1], sys.argv[2])
    size = sum(os.path.getsize(os.path.join(sys.argv[2], name)) for name in files)
    print(f"copied {len(files)} files, {size / 1e6:.1f} MB, into {sys.argv[2]}")
