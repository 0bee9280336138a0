"""The experiment folder: what every command that writes results writes through.

One abstraction for the output folder of ``compare``, ``table61``, ``analyze``,
``reproduce`` and its chapters, ``bench integrate``, ``render`` and ``show``
(issue 18). A folder holds a manifest, ``sparselt-folder.json``::

    {"format": "sparselt-experiment-folder", "format_version": 1,
     "kind": "compare",                 # which command's folder
     "identity": {...},                 # the full configuration, defaults explicit
     "scene": {...},                    # the scene's content identity (rendering.identity), or null
     "status": "running" | "complete",  # complete only when every cell is in
     "files": [...],                    # every file sparselt wrote here (relative paths)
     "history": [...]}                  # every command that contributed: versions, git, times

and keeps five promises:

- **Identity.** A rerun with the same identity resumes; one with another
  identity is refused, naming what differs, unless ``overwrite``. Stating a
  default is the same identity (callers make every default explicit).
- **Lock.** One writer at a time (:class:`~sparselt.storage.lock.StoreLock`);
  a second is refused naming the holder's PID, host and command.
- **Nothing foreign is touched.** A folder holding files the manifest does
  not list is refused, ``overwrite`` or not. ``overwrite`` removes only the
  files the manifest lists, and only in :meth:`ExperimentFolder.open`, which
  callers enter after the new configuration is validated and the scene has
  loaded.
- **Atomic artefacts.** Every file goes through
  :func:`sparselt.provenance.atomic_write` (temporary file, fsync, rename)
  and is listed in the manifest *before* it is created, so a run killed at
  any point leaves nothing that looks like a foreign file, and nothing
  half-written under a final name.
- **Nothing left by a failure.** A run that fails in a folder it created,
  before any cell was recorded, removes what it wrote there (its lock
  included) and the folders it created; a failure in an existing folder
  leaves its finished work and no lock. A full disk names the path being
  written (:class:`~sparselt.storage.errors.DiskFullError`), the lock's
  own record included.

Resumable cells are JSON records under ``cells/``: a cell is done when its
record exists (its folder's identity was checked when the folder opened).
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import sys
from datetime import datetime, timezone

from ..digest import bytes_digest, canonical
from ..provenance import atomic_write, atomic_write_bytes, environment_record, read_json
from .errors import caused_by_interrupt, no_space_is_clear, output_path_problem
from .lock import LOCK_FILE, LOCK_REMEDY, StoreLock, check_unlocked

MANIFEST_FILE = "sparselt-folder.json"
FORMAT = "sparselt-experiment-folder"
FORMAT_VERSION = 1
CELLS = "cells"
REPEATS = "repeats"
TEMPORARY_PREFIX = ".tmp-"


class FolderError(ValueError):
    """An output folder that cannot take this run (foreign files, another identity, a file in the way)."""


def _now():
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def _json_default(value):
    if hasattr(value, "tolist"):
        return value.tolist()
    raise TypeError(f"cannot store {type(value).__name__} in an identity")


def _flattened(identity, growable):
    """The identity with each growable key's entries as ``key.entry`` (growable values are dicts)."""
    flat = {}
    for key, value in identity.items():
        if key in growable and isinstance(value, dict):
            flat.update({f"{key}.{entry}": item for entry, item in value.items()})
        else:
            flat[key] = value
    return flat


def identity_differences(recorded, current, limit=3, growable=()):
    """``'key: recorded -> current'`` for the keys whose values differ (at most ``limit``, then '...').

    A ``growable`` key's entries are compared one by one, and only those both
    identities hold (an entry one of them lacks is not a difference).
    """
    recorded, current = _flattened(recorded, growable), _flattened(current, growable)
    keys = sorted(set(recorded) | set(current))
    optional = tuple(f"{key}." for key in growable)
    changed = [key for key in keys if recorded.get(key) != current.get(key)
               and not (key.startswith(optional) and (key not in recorded or key not in current))]
    text = [f"{key}: {_short(recorded.get(key, '(absent)'))} recorded, {_short(current.get(key, '(absent)'))} now"
            for key in changed[:limit]]
    return "; ".join(text) + (f"; and {len(changed) - limit} more" if len(changed) > limit else "")


def _short(value):
    text = json.dumps(value, sort_keys=True) if not isinstance(value, str) else repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _is_ours(name):
    return name in (MANIFEST_FILE, LOCK_FILE) or name.startswith(TEMPORARY_PREFIX)


class ExperimentFolder:
    """An experiment's output folder (see the module docstring).

    Parameters
    ----------
    path : str or os.PathLike
        The folder.
    kind : str
        The command writing it ('compare', 'table61', 'analyze', ...); a
        folder of another kind is refused like another identity.
    identity : dict
        Everything that determines the results, defaults made explicit,
        JSON-serialisable. Lists a rerun may extend (a comparison's methods,
        budgets, seeds) do not belong here.
    scene : dict, optional
        The scene's content identity (:func:`sparselt.rendering.identity.scene_identity`);
        its ``digest`` is part of the identity and, when it differs, the
        message names the changed files.
    overwrite : bool, optional
        Replace a folder of another identity (only the files it lists).
    growable : tuple of str, optional
        Identity keys whose values are dicts a rerun may extend (a
        comparison's per-method options, as it may add methods): entries both
        runs hold must be equal, new entries join the recorded identity.

    Notes
    -----
    Use in three steps: :meth:`inspect` (refusals, no change on disk) before
    any expensive work; load the scene; then ``with folder.open(): ...``,
    which takes the lock, removes the old files if replacing, and records this
    command in the history.
    """

    def __init__(self, path, *, kind, identity, scene=None, overwrite=False, growable=()):
        path = os.fspath(path)
        if "://" in path:
            raise FolderError(f"output {path!r}: only file-system paths are supported, not URLs")
        self.path = os.path.abspath(path)
        self.kind = kind
        self.identity = canonical(identity)  # as stored: tuples become lists, so identities compare as read back
        self.scene = canonical(scene) if scene is not None else None
        self.overwrite = bool(overwrite)
        self.growable = tuple(growable)
        self.manifest = None
        self.plan = None
        self._lock = None
        self._locking = False
        self._files = set()
        #: Cells and repeats recorded by this run (:meth:`record_cell`, :meth:`record_repeat`).
        self.recorded = 0
        #: Cells this run attempted and did not keep (an experiment's ``Unfinished`` outcomes: tried again on a rerun).
        self.attempted = 0

    # ----------------------------------------------------------------- inspection (changes nothing)
    @property
    def full_identity(self):
        """The identity with the scene's digest: what a resume must find unchanged."""
        identity = dict(self.identity)
        if self.scene is not None:
            identity["scene_digest"] = self.scene.get("digest")
        return identity

    def inspect(self):
        """Decide what to do with the folder: 'new', 'resume' or 'replace'; raise :class:`FolderError` to refuse.

        Nothing is written or removed.
        """
        path = self.path
        problem = output_path_problem(path)  # a link loop, a broken link, a file, a file in the way
        if problem:
            raise FolderError(f"output path {path!r} {problem}")
        exists = os.path.isdir(path)
        if not exists:
            self._check_creatable()
            self.plan = "new"
            return self.plan
        if not os.access(path, os.W_OK | os.X_OK):
            raise PermissionError(f"output folder {path!r} is not writable")
        if self._lock is None and not self._locking:  # our own lock is not another writer
            check_unlocked(path, what=f"{self.kind} folder")
        manifest_path = os.path.join(path, MANIFEST_FILE)
        entries = sorted(os.listdir(path))
        if not os.path.isfile(manifest_path):
            foreign = [name for name in entries if not _is_ours(name)]
            if foreign:
                raise FolderError(
                    f"output folder {path!r} holds files sparselt did not write ({_listing(foreign)}); nothing was "
                    "changed: choose another --out (sparselt never deletes what it did not write)")
            self.plan = "new"
            return self.plan
        manifest = self._read_manifest(manifest_path)
        foreign = self._foreign(manifest, entries)
        if foreign:
            raise FolderError(
                f"output folder {path!r} holds files its manifest does not list ({_listing(foreign)}); nothing was "
                "changed: move them away or choose another --out (sparselt never deletes what it did not write)")
        self.manifest = manifest
        if manifest.get("kind") != self.kind:
            if not self.overwrite:
                raise FolderError(f"output folder {path!r} holds a {manifest.get('kind')!r} run, not a {self.kind!r} "
                                  "one; choose another --out or pass --overwrite to replace it")
            self.plan = "replace"
            return self.plan
        recorded = dict(manifest.get("identity") or {})
        if manifest.get("scene") is not None:
            recorded["scene_digest"] = manifest["scene"].get("digest")
        if not identity_differences(recorded, self.full_identity, growable=self.growable):
            self.plan = "resume"
            return self.plan
        if self.overwrite:
            self.plan = "replace"
            return self.plan
        difference = identity_differences(recorded, self.full_identity, growable=self.growable)
        if recorded.get("scene_digest") != self.full_identity.get("scene_digest"):
            from ..rendering.identity import describe_scene_change

            change = describe_scene_change(manifest.get("scene") or {}, self.scene or {})
            difference += f" ({change})" if change else ""
        raise FolderError(f"output folder {path!r} holds another {self.kind} run ({difference}); resuming would mix "
                          "the two: choose another --out, or pass --overwrite to replace it")

    def _check_creatable(self):
        probe = os.path.dirname(self.path)
        while not os.path.exists(probe):
            probe = os.path.dirname(probe)
        if not os.access(probe, os.W_OK | os.X_OK):
            raise PermissionError(f"output folder {self.path!r} cannot be created (no write permission on {probe!r})")

    def read_manifest(self):
        """The folder's manifest, checked, for a reader: no lock is taken and nothing is written.

        Raises
        ------
        FolderError
            The path is not a folder, holds no sparselt manifest (or a
            damaged one), or holds a folder of another kind than
            :attr:`kind`; the message names the path.
        """
        manifest_path = os.path.join(self.path, MANIFEST_FILE)
        if not os.path.isfile(manifest_path):
            raise FolderError(f"{self.path!r} is not a sparselt {self.kind} folder: it holds no {MANIFEST_FILE}")
        manifest = self._read_manifest(manifest_path)
        if manifest["kind"] != self.kind:
            raise FolderError(f"{self.path!r} holds a {manifest['kind']!r} run, not a {self.kind!r} one")
        return manifest

    def _read_manifest(self, manifest_path):
        manifest = read_json(manifest_path)
        if not isinstance(manifest, dict) or manifest.get("format") != FORMAT:
            raise FolderError(f"{manifest_path!r} is not a sparselt folder manifest; choose another --out")
        if manifest.get("format_version") != FORMAT_VERSION:
            raise FolderError(f"{manifest_path!r} has format version {manifest.get('format_version')!r}; this "
                              f"sparselt reads version {FORMAT_VERSION}: choose another --out")
        for key in ("kind", "identity", "files", "history", "status"):
            if key not in manifest:
                raise FolderError(f"{manifest_path!r} lacks {key!r}; the manifest is damaged: choose another --out")
        return manifest

    def _foreign(self, manifest, entries):
        """Entries of the folder that neither the manifest lists nor sparselt's own bookkeeping explains.

        A listed sub-folder (``name/``: a signal store or another experiment
        folder inside this one) is checked by its own owner when it is opened.
        """
        listed = set(manifest.get("files") or [])
        folders = {name.split("/", 1)[0] for name in listed if "/" in name}
        foreign = []
        for name in entries:
            if _is_ours(name) or name in listed or name + "/" in listed:
                continue
            if name in folders and os.path.isdir(os.path.join(self.path, name)):
                for root, _, files in os.walk(os.path.join(self.path, name)):
                    for file in files:
                        relative = os.path.relpath(os.path.join(root, file), self.path).replace(os.sep, "/")
                        if (relative not in listed and not file.startswith(TEMPORARY_PREFIX)
                                and not any(relative.startswith(owned) for owned in listed if owned.endswith("/"))):
                            foreign.append(relative)
                continue
            foreign.append(name)
        return foreign

    # ----------------------------------------------------------------- the run
    @contextlib.contextmanager
    def open(self):
        """Take the folder: lock, replace if planned, record this command; release the lock on exit.

        A run that fails (an exception, not an interruption) in a folder this
        call created, before any cell or sub-folder was recorded, leaves
        nothing behind: the files it listed, its manifest, its lock and the
        folders it created are removed (nothing else is ever there, and
        nothing a rerun could resume is lost).
        """
        if self.plan is None:
            self.inspect()
        created = missing_folders(self.path)
        with no_space_is_clear(self.path, "creating the output folder", LOCK_REMEDY):
            os.makedirs(self.path, exist_ok=True)
        lock = StoreLock(self.path, what=f"{self.kind} folder")
        try:
            lock.acquire()
        except BaseException:
            remove_empty_folders(created)
            raise
        failed = False
        try:
            self._locking = True
            self.inspect()  # again, now that the folder is ours
            self._locking = False
            if self.plan == "replace":
                self._remove_listed(self.manifest)
                self.manifest = None
            previous = self.manifest or {}
            for key in self.growable:  # a resumed run keeps what the earlier runs recorded
                earlier = (previous.get("identity") or {}).get(key)
                if isinstance(earlier, dict) and isinstance(self.identity.get(key), dict):
                    self.identity[key] = dict(earlier, **self.identity[key])
            self._files = set(previous.get("files") or [])
            history = list(previous.get("history") or [])
            history.append(dict(environment_record(), started=_now(), plan=self.plan))
            self.manifest = {"format": FORMAT, "format_version": FORMAT_VERSION, "kind": self.kind,
                             "identity": self.identity, "scene": self.scene, "status": "running",
                             "files": sorted(self._files), "history": history}
            self._write_manifest()
            self._lock = lock
            yield self
        except Exception:
            failed = True
            raise
        finally:
            self._lock = None
            self._locking = False
            lock.release()
            # The exception in flight decides: a Ctrl-C (a KeyboardInterrupt, drjit.custom's RuntimeError around
            # one, or a Mitsuba render's cancellation followed by the KeyboardInterrupt) is an interruption, whose
            # folder a rerun resumes.
            if failed and created and not caused_by_interrupt(sys.exc_info()[1]):
                self._discard_unfinished(created)

    def _discard_unfinished(self, created):
        """After a failed run in folders this run created (``created``, deepest first): remove what it wrote,
        unless a cell, a repeat or a sub-folder was recorded (work a rerun resumes)."""
        if any(name.endswith("/") or name.startswith((f"{CELLS}/", f"{REPEATS}/")) for name in self._files):
            return
        with contextlib.suppress(OSError):
            _remove_listed_files(self.path, sorted(self._files))
            manifest_path = os.path.join(self.path, MANIFEST_FILE)
            if os.path.isfile(manifest_path):
                os.remove(manifest_path)
        remove_empty_folders(created)

    def _remove_listed(self, manifest):
        """Remove the files a manifest lists (never anything else), then the folders they leave empty."""
        _remove_listed_files(self.path, manifest.get("files") or [])
        os.remove(os.path.join(self.path, MANIFEST_FILE))

    def _write_manifest(self):

        self.manifest["files"] = sorted(self._files)
        atomic_write_bytes(os.path.join(self.path, MANIFEST_FILE),
                           (json.dumps(self.manifest, indent=1, default=_json_default) + "\n").encode())

    def _require_open(self):
        if self._lock is None:
            raise RuntimeError(f"internal error: write to {self.path!r} outside 'with folder.open()'")

    def path_of(self, name):
        """Absolute path of ``name`` (a '/'-separated path relative to the folder)."""
        return os.path.join(self.path, *name.split("/"))

    def exists(self, name):
        return os.path.isfile(self.path_of(name))

    def claim_folder(self, name):
        """List sub-folder ``name`` as sparselt's (a signal store or an experiment folder with its own manifest);
        return its path, created."""
        self.claim(name.rstrip("/") + "/")
        target = self.path_of(name.rstrip("/"))
        os.makedirs(target, exist_ok=True)
        return target

    def claim(self, *names):
        """List ``names`` in the manifest before they are written (one manifest write for all new ones)."""
        self._require_open()
        new = [name for name in names if name not in self._files]
        if new:
            self._files.update(new)
            self._write_manifest()

    # ----------------------------------------------------------------- the one writer
    def write_with(self, name, write):
        """Write ``name`` atomically with ``write(temporary_path)`` (see :func:`~sparselt.provenance.atomic_write`)."""
        self.claim(name)
        target = self.path_of(name)
        os.makedirs(os.path.dirname(target), exist_ok=True)
        atomic_write(target, write)
        return target

    def write_bytes(self, name, data):
        def write(temporary):
            with open(temporary, "wb") as handle:
                handle.write(data)

        return self.write_with(name, write)

    def write_text(self, name, text):
        return self.write_bytes(name, text.encode("utf-8"))

    def write_json(self, name, record):
        from ..provenance import _json_default as provenance_default

        return self.write_text(name, json.dumps(record, indent=2, default=provenance_default) + "\n")

    def write_npy(self, name, array):
        import numpy as np

        buffer = io.BytesIO()
        np.save(buffer, array)
        return self.write_bytes(name, buffer.getvalue())

    def write_png(self, name, image, *, exposure=1.0):
        """A linear ``(height, width, 3)`` image, tone-mapped (:func:`sparselt.image_io.png_bytes`)."""
        from ..image_io import png_bytes

        return self.write_bytes(name, png_bytes(image, exposure=exposure))

    def write_figure(self, name, figure, **options):
        """A matplotlib figure as PNG; the figure is closed."""
        from ..image_io import figure_bytes

        return self.write_bytes(name, figure_bytes(figure, **options))

    def write_exr(self, name, image):
        """A float32 ``(height, width, 3)`` image as OpenEXR (:func:`sparselt.image_io.exr_bytes`)."""
        from ..image_io import exr_bytes

        return self.write_bytes(name, exr_bytes(image))

    def write_image(self, stem, image, *, exposure=1.0):
        """``stem.npy`` (float32), ``stem.exr`` and ``stem.png``: the three forms of every result image."""
        import numpy as np

        self.claim(stem + ".npy", stem + ".exr", stem + ".png")
        self.write_npy(stem + ".npy", np.asarray(image, dtype=np.float32))
        self.write_exr(stem + ".exr", image)
        self.write_png(stem + ".png", image, exposure=exposure)

    def write_table(self, stem, table):
        """A :class:`sparselt.report.Table` as ``stem.md`` and ``stem.csv``."""
        self.claim(stem + ".md", stem + ".csv")
        self.write_text(stem + ".md", table.markdown())
        self.write_text(stem + ".csv", table.csv())

    def read_json(self, name):
        return read_json(self.path_of(name))

    # ----------------------------------------------------------------- cells and status
    def cell(self, name):
        """The record of a finished cell, or ``None``."""
        path = self.path_of(f"{CELLS}/{name}.json")
        return read_json(path) if os.path.isfile(path) else None

    def cells(self):
        """Every finished cell's record, by name."""
        folder = self.path_of(CELLS)
        if not os.path.isdir(folder):
            return {}
        return {name[:-5]: read_json(os.path.join(folder, name)) for name in sorted(os.listdir(folder))
                if name.endswith(".json") and not name.startswith(TEMPORARY_PREFIX)}

    def record_cell(self, name, record):
        """Record a finished cell (after its artefacts are written)."""
        self.recorded += 1
        return self.write_json(f"{CELLS}/{name}.json", record)

    def repeats(self, name):
        """The timing repeats of cell ``name`` recorded so far (its record under ``repeats/``), or ``None``.

        A cell run several times (a comparison's timing repeats, in rounds over
        every cell) records each repeat as it finishes, so a run interrupted
        between rounds resumes within the round; the cell itself enters
        ``cells/`` only with all its repeats (:meth:`record_cell`).
        """
        path = self.path_of(f"{REPEATS}/{name}.json")
        return read_json(path) if os.path.isfile(path) else None

    def repeat_names(self):
        """The names of the cells with repeats recorded (:meth:`repeats`), sorted."""
        folder = self.path_of(REPEATS)
        if not os.path.isdir(folder):
            return []
        return [name[:-5] for name in sorted(os.listdir(folder))
                if name.endswith(".json") and not name.startswith(TEMPORARY_PREFIX)]

    def record_repeat(self, name, record):
        """Record the repeats of cell ``name`` so far (see :meth:`repeats`)."""
        self.recorded += 1
        return self.write_json(f"{REPEATS}/{name}.json", record)

    def complete(self, **summary):
        """Mark the folder complete (every cell is in); ``summary`` goes into this command's history entry."""
        self._require_open()
        self.manifest["status"] = "complete"
        self.manifest["history"][-1].update(summary, finished=_now())
        self._write_manifest()

    @property
    def status(self):
        return (self.manifest or {}).get("status")


def signal_identity(signal):
    """What identifies a stored signal's content for a folder derived from it (``show``, ``analyze``): its
    acquisition configuration, scene digest and a digest of its chunk checksums (not where it is stored)."""
    meta = signal.meta or {}
    checksums = json.dumps(meta.get("chunk_crc32") or [], separators=(",", ":")).encode()
    return {"kind": signal.kind, "shape": list(signal.shape), "config": meta.get("config"),
            "scene_digest": (meta.get("scene_identity") or {}).get("digest"),
            "content_digest": bytes_digest(checksums) if meta.get("chunk_crc32") else None}


def _remove_listed_files(root, names):
    """Remove the listed files under ``root``; a listed sub-folder (``name/``) loses only what its own
    manifest or signal store says sparselt wrote. Folders left empty go too; nothing else is touched."""
    folders = set()
    for name in names:
        target = os.path.join(root, name.rstrip("/"))
        if name.endswith("/"):
            _remove_owned_folder(target)
        elif os.path.isfile(target) or os.path.islink(target):
            os.remove(target)
        parent = os.path.dirname(name.rstrip("/"))
        while parent:
            folders.add(parent)
            parent = os.path.dirname(parent)
    for folder in sorted(folders, key=lambda name: -name.count("/")):
        with contextlib.suppress(OSError):
            os.rmdir(os.path.join(root, folder))
    for name in os.listdir(root):
        if name.startswith(TEMPORARY_PREFIX):
            os.remove(os.path.join(root, name))


def _remove_owned_folder(path):
    """Empty a sub-folder sparselt owns: experiment folders by their manifests, signal stores by their format."""
    from .zarr_store import remove_store, store_status

    if not os.path.isdir(path):
        return
    manifest_path = os.path.join(path, MANIFEST_FILE)
    if os.path.isfile(manifest_path):
        manifest = read_json(manifest_path)
        _remove_listed_files(path, manifest.get("files") or [])
        os.remove(manifest_path)
    elif store_status(path) is not None:
        remove_store(path)
    else:
        for name in os.listdir(path):
            if os.path.isdir(os.path.join(path, name)):
                _remove_owned_folder(os.path.join(path, name))
    with contextlib.suppress(OSError):
        os.rmdir(path)


def missing_folders(path):
    """The folders ``os.makedirs(path)`` would create, deepest first."""
    missing = []
    while not os.path.lexists(path):
        missing.append(path)
        parent = os.path.dirname(path)
        if parent == path:
            break
        path = parent
    return missing


def remove_empty_folders(folders):
    """Remove ``folders`` (deepest first) while they are empty; stop at the first that is not."""
    for folder in folders:
        try:
            os.rmdir(folder)
        except OSError:
            return


def _listing(names):
    return ", ".join(repr(name) for name in names[:3]) + (f" and {len(names) - 3} more" if len(names) > 3 else "")


__all__ = ["ExperimentFolder", "FolderError", "MANIFEST_FILE", "identity_differences", "missing_folders",
           "remove_empty_folders", "signal_identity"]
