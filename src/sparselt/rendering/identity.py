"""A scene's identity: what a resumed acquisition must find unchanged.

A signal is resumed only if its scene is the same one. For a Mitsuba XML file
that is the bytes of the file and of every file it references (meshes,
textures, included XML files, recursively); for a built-in or programmatic
scene it is the scene description (every parameter, with the content of every
file it names) and the code version of the modules that generate the built-in
scenes. Plain Python: the renderer is not needed.
"""

from __future__ import annotations

import hashlib
import json
import os
import xml.etree.ElementTree as ElementTree
from dataclasses import asdict, is_dataclass

_GENERATOR_MODULES = ("scenes.py", "procedural.py", "meshes.py")


def file_digest(path):
    """SHA-256 of a file's bytes."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def xml_references(path):
    """Every file an XML scene references, recursively through ``<include>``; absolute paths, sorted.

    References are ``filename`` attributes (``<include filename=...>``) and
    ``<string name="filename" value=...>`` properties, with ``$name``
    defaults substituted, resolved against the XML file's folder.
    """
    seen, pending, found = set(), [os.path.abspath(path)], set()
    while pending:
        current = pending.pop()
        if current in seen:
            continue
        seen.add(current)
        try:
            root = ElementTree.parse(current).getroot()
        except (ElementTree.ParseError, OSError):
            continue
        defaults = {node.get("name"): node.get("value") for node in root.iter("default")}
        folder = os.path.dirname(current)

        def resolve(text):
            for name, value in defaults.items():
                text = text.replace(f"${name}", value or "")
            return os.path.normpath(os.path.join(folder, text))

        for node in root.iter():
            names = []
            if node.tag == "include" and node.get("filename"):
                names.append(node.get("filename"))
            if node.tag == "string" and node.get("name") == "filename" and node.get("value"):
                names.append(node.get("value"))
            for name in names:
                target = resolve(name)
                found.add(target)
                if node.tag == "include" and target.lower().endswith(".xml"):
                    pending.append(target)
    return sorted(found)


def _generator_version():
    folder = os.path.dirname(os.path.abspath(__file__))
    digest = hashlib.sha256()
    for name in _GENERATOR_MODULES:
        with open(os.path.join(folder, name), "rb") as handle:
            digest.update(name.encode() + b"\0" + handle.read())
    return digest.hexdigest()


def _describe_value(value, files):
    if is_dataclass(value):
        return {"__class__": type(value).__name__, **{k: _describe_value(v, files) for k, v in asdict(value).items()}}
    if isinstance(value, dict):
        described = {}
        for key, item in value.items():
            if key == "filename" and isinstance(item, str):
                files.append(item)
                described[key] = os.path.basename(item)
            else:
                described[key] = _describe_value(item, files)
        return described
    if isinstance(value, (list, tuple)):
        return [_describe_value(item, files) for item in value]
    if hasattr(value, "tolist"):
        return value.tolist()
    if isinstance(value, (str, int, float, bool)) or value is None:
        return value
    return repr(value)


def scene_identity(spec):
    """Identity record of a :class:`~sparselt.rendering.scenes.SceneSpec`.

    Returns
    -------
    dict
        ``{"digest": hex, "files": {path: sha256 or "missing"}, ...}``; two
        scenes are the same when their digests are.
    """
    files = {}
    if spec.filename is not None:
        names = [os.path.abspath(spec.filename)] + xml_references(spec.filename)
        record = {"source": "xml", "file": os.path.abspath(spec.filename)}
    else:
        names = []
        record = {"source": "description", "generator_version": _generator_version(),
                  "description": _describe_value({"objects": spec.objects, "camera": spec.camera,
                                                  "hide_emitters": spec.hide_emitters}, names)}
    for name in names:
        files[name] = file_digest(name) if os.path.isfile(name) else "missing"
    record["lens_overrides"] = dict(sorted(spec.lens_overrides.items()))
    # The digest covers file contents, not where they are: a scene copied elsewhere stays the same scene.
    content = dict(record, file=None, files=sorted(files.values()))
    record["files"] = files
    record["digest"] = hashlib.sha256(json.dumps(content, sort_keys=True).encode()).hexdigest()
    return record
