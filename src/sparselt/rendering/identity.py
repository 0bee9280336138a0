"""A scene's identity: what a resumed acquisition must find unchanged.

A signal is resumed only if its scene is the same one. For a Mitsuba XML file
that is the bytes of the file and of every file it references (meshes,
textures, included XML files, recursively); for a built-in or programmatic
scene it is the scene description (every parameter, with the content of every
file it names) and the code version of the modules that generate the built-in
scenes. Plain Python: the renderer is not needed.
"""

from __future__ import annotations

import os
import re
import xml.etree.ElementTree as ElementTree
from dataclasses import asdict, dataclass, is_dataclass

from ..digest import bytes_digest, digest, file_digest

_GENERATOR_MODULES = ("scenes.py", "procedural.py", "standard_scenes.py", "meshes.py")




_PARAMETER = re.compile(r"\$([A-Za-z_][A-Za-z0-9_]*)")


@dataclass(frozen=True)
class XmlReference:
    """One file a Mitsuba XML scene references.

    Attributes
    ----------
    xml : str
        The XML file holding the element (the scene file or an included one).
    element : str
        The element naming the file, as written, e.g. ``<shape type="ply" id="bunny">``.
    plugin : str
        ``'include'``, or the plugin type of that element (``'ply'``, ``'obj'``, ``'bitmap'``, ...).
    path : str
        Absolute path, resolved as Mitsuba resolves it.
    unresolved : bool
        The name still holds a ``$name`` without a value (Mitsuba reports it as an undefined parameter).
    """

    xml: str
    element: str
    plugin: str
    path: str
    unresolved: bool = False


def _describe_element(node):
    attributes = "".join(f' {key}="{node.get(key)}"' for key in ("type", "name", "id", "filename") if node.get(key))
    return f"<{node.tag}{attributes}>"


def _resolve_reference(name, folders):
    """``name`` as Mitsuba's file resolver finds it: the first of ``folders`` holding it, else in the first folder."""
    if os.path.isabs(name):
        return os.path.normpath(name)
    for folder in folders:
        candidate = os.path.normpath(os.path.join(folder, name))
        if os.path.exists(candidate):
            return candidate
    return os.path.normpath(os.path.join(folders[0], name))


def xml_reference_records(path, parameters=()):
    """Every file an XML scene references, recursively through ``<include>``, as :class:`XmlReference` records.

    Parameters
    ----------
    path : str
        The Mitsuba XML scene file.
    parameters : sequence of (str, str), optional
        Values of ``$name`` parameters (``-D name=value``); they take
        precedence over the files' ``<default>`` values, as in Mitsuba.

    Notes
    -----
    References are ``<include filename=...>`` elements and ``<string
    name="filename" value=...>`` properties. A relative name is resolved as
    Mitsuba's file resolver does while loading the scene: against the scene
    file's folder first (also for references inside included files), then the
    including file's folder and the working directory.
    """
    main = os.path.abspath(path)
    given = {str(name): str(value) for name, value in parameters}
    seen, pending, records = set(), [(main, {})], []
    while pending:
        current, inherited = pending.pop()
        if current in seen:
            continue
        seen.add(current)
        try:
            root = ElementTree.parse(current).getroot()
        except (ElementTree.ParseError, OSError):
            continue
        values = dict(inherited)
        for node in root.iter("default"):
            values.setdefault(node.get("name"), node.get("value") or "")
        values.update(given)
        folders = [os.path.dirname(main), os.path.dirname(current), os.getcwd()]

        def substitute(text):
            return _PARAMETER.sub(lambda match: values.get(match.group(1), match.group(0)), text)

        for parent in root.iter():
            for node in parent:
                if node.tag == "include" and node.get("filename"):
                    name, element, plugin = node.get("filename"), _describe_element(node), "include"
                elif node.tag == "string" and node.get("name") == "filename" and node.get("value"):
                    name, element, plugin = node.get("value"), _describe_element(parent), parent.get("type") or parent.tag
                else:
                    continue
                name = substitute(name)
                target = _resolve_reference(name, folders)
                records.append(XmlReference(current, element, plugin, target, unresolved=bool(_PARAMETER.search(name))))
                if plugin == "include" and target.lower().endswith(".xml"):
                    pending.append((target, values))
    return records


def xml_references(path, parameters=()):
    """Every file an XML scene references (:func:`xml_reference_records`); absolute paths, sorted."""
    return sorted({reference.path for reference in xml_reference_records(path, parameters)})


_IMAGE_MAGIC = (b"\x89PNG", b"\xff\xd8\xff", b"\x76\x2f\x31\x01", b"#?", b"PF", b"Pf", b"P3", b"P6", b"BM")
_OBJ_KEYWORDS = frozenset("v vt vn vp f l p o g s usemtl mtllib cstype deg bmat step curv curv2 surf parm trim hole "
                          "scrv sp end con mg bevel c_interp d_interp lod shadow_obj trace_obj ctech stech".split())
_MESH_FORMATS = {"ply": "a PLY mesh (a PLY file starts with 'ply')",
                 "obj": "a Wavefront OBJ mesh (text lines starting with v, vt, vn, f, o, g, # ...)",
                 "serialized": "a Mitsuba serialized mesh (it starts with the bytes 1C 04)"}

_HEAD_BYTES = 1 << 16


def _plausible_obj(head):
    if b"\0" in head:
        return False
    try:
        text = head.decode("utf-8")
    except UnicodeDecodeError:
        return False
    lines = text.splitlines()
    if len(head) == _HEAD_BYTES and lines:
        lines = lines[:-1]  # the last line read may be cut short
    words = [line.split(None, 1)[0] for line in lines if line.strip()]
    return bool(words) and all(word.startswith("#") or word in _OBJ_KEYWORDS for word in words)


def _reference_problem(reference):
    """Why ``reference`` cannot be what its element expects, or None."""
    if not os.path.exists(reference.path):
        return "which does not exist"
    if not os.path.isfile(reference.path):
        return "which is not a regular file"
    try:
        with open(reference.path, "rb") as handle:
            head = handle.read(_HEAD_BYTES)
    except OSError as error:
        return f"which cannot be read ({error.strerror or error})"
    plugin = reference.plugin
    if plugin in _MESH_FORMATS:
        valid = {"ply": head[:3] == b"ply", "serialized": head[:2] == b"\x1c\x04", "obj": _plausible_obj(head)}[plugin]
        return None if valid else f"which is not {_MESH_FORMATS[plugin]}"
    if plugin == "include":
        try:
            ElementTree.parse(reference.path)
        except ElementTree.ParseError as error:
            return f"which is not an XML file ({error})"
        return None
    if plugin in ("bitmap", "envmap") and not (head.startswith(_IMAGE_MAGIC) or reference.path.lower().endswith(".tga")):
        return "which is not an image Mitsuba reads (PNG, JPEG, OpenEXR, RGBE, PFM, PPM, BMP or TGA)"
    return None


def check_xml_references(path, parameters=()):
    """Refuse an XML scene whose referenced files are missing or not of the type their element expects.

    Mitsuba itself reports such files late and obscurely (a text file given as
    a PLY mesh fails in "Storing new normals"); this check runs before the
    scene is loaded.

    Parameters
    ----------
    path : str
        The Mitsuba XML scene file.
    parameters : sequence of (str, str), optional
        ``$name`` values, as for :func:`xml_reference_records`.

    Raises
    ------
    ValueError
        Naming the XML file, the element and the path: a missing file, a
        folder or device, a mesh (``ply``, ``obj``, ``serialized``) whose
        content is not of that format, an include that is not XML, an image
        of an unknown format.
    """
    for reference in xml_reference_records(path, parameters):
        if reference.unresolved:
            continue
        problem = _reference_problem(reference)
        if problem is not None:
            raise ValueError(f"scene file {reference.xml!r}: {reference.element} references {reference.path!r}, {problem}")


def _generator_version():
    folder = os.path.dirname(os.path.abspath(__file__))
    parts = []
    for name in _GENERATOR_MODULES:
        with open(os.path.join(folder, name), "rb") as handle:
            parts.append(name.encode() + b"\0" + handle.read())
    return bytes_digest(*parts)


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

    The one scene identity of sparselt: a signal's resume check and the
    reference image cache both use it. A scene file: its bytes, those of every
    file it references (:func:`xml_references`, with the ``-D`` parameters
    substituted) and the parameters; a built-in or programmatic scene: its
    description and the code of the modules generating built-in scenes.
    Both: the lens overrides.

    Returns
    -------
    dict
        ``{"digest": hex, "files": {path: sha256 or "missing"}, ...}``; two
        scenes are the same when their digests are.
    """
    files = {}
    if spec.filename is not None:
        names = [os.path.abspath(spec.filename)] + xml_references(spec.filename, spec.parameters)
        record = {"source": "xml", "file": os.path.abspath(spec.filename)}
    else:
        names = []
        record = {"source": "description", "generator_version": _generator_version(),
                  "description": _describe_value({"objects": spec.objects, "camera": spec.camera,
                                                  "hide_emitters": spec.hide_emitters}, names)}
    for name in names:
        files[name] = file_digest(name) if os.path.isfile(name) else "missing"
    record["lens_overrides"] = dict(sorted(spec.lens_overrides.items()))
    if spec.parameters:  # only when given, so that the digests of scenes without parameters stay as they were
        record["parameters"] = [list(pair) for pair in spec.parameters]
    # The digest covers file contents, not where they are: a scene copied elsewhere stays the same scene.
    content = dict(record, file=None, files=sorted(files.values()))
    record["files"] = files
    record["digest"] = digest(content)
    return record


def describe_scene_change(recorded, current):
    """What changed between two :func:`scene_identity` records, for messages: the changed files, or the
    description (built-in scenes); '' when neither tells."""
    before, after = (recorded or {}).get("files") or {}, (current or {}).get("files") or {}
    names = [name for name in sorted(set(before) | set(after)) if before.get(name) != after.get(name)]
    if names:
        return "changed: " + ", ".join(names[:3]) + (" ..." if len(names) > 3 else "")
    if (recorded or {}).get("source") == "description":
        return "its description or the code generating it changed"
    return ""
