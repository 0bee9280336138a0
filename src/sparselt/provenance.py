"""Provenance and safe file writing shared by every command that writes output.

Every output folder records its resolved configuration, seed, package versions
and git revision (:func:`environment_record`). Files are written atomically:
to a temporary name in the same folder, flushed, then renamed over the final
name, so an interrupted run never leaves a half-written file under a final name.
"""

from __future__ import annotations

import io
import json
import os
import platform
import subprocess
import sys
import tempfile
from datetime import datetime, timezone
from importlib import metadata

PACKAGES = ("sparselt", "numpy", "scipy", "mitsuba", "drjit", "ducc0", "matplotlib", "tqdm", "numba", "pyoidn", "zarr",
            "dask", "distributed")


def package_versions():
    """Installed versions of the packages sparselt depends on (``None`` when absent)."""
    versions = {"python": platform.python_version()}
    for name in PACKAGES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = None
    return versions


def git_revision():
    """``{'commit': sha, 'dirty': bool}`` of the source checkout, or ``None`` outside git."""
    folder = os.path.dirname(os.path.abspath(__file__))
    try:
        commit = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=folder, capture_output=True, text=True, timeout=10, check=True
        ).stdout.strip()
        status = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=folder, capture_output=True, text=True, timeout=10, check=True,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None
    return {"commit": commit, "dirty": bool(status)}


_COMMAND = []


def record_command(arguments):
    """Set the command line :func:`environment_record` reports (the CLI's own arguments, also when
    ``sparselt.cli.main`` is called from Python); by default it is ``sys.argv``."""
    _COMMAND[:] = [str(argument) for argument in arguments]


def recorded_command():
    """The command line :func:`environment_record` reports: the one :func:`record_command` set, else ``sys.argv``."""
    return list(_COMMAND) or list(sys.argv)


def environment_record():
    """Versions, git revision, platform, command line and time: attach to every output."""
    return {
        "versions": package_versions(),
        "git": git_revision(),
        "platform": platform.platform(),
        "command": recorded_command(),
        "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
    }


def atomic_write(path, write):
    """The one atomic writer: ``write(temporary_path)`` fills a temporary file beside ``path``, then fsync, rename.

    Every artefact sparselt writes (EXR, PNG, CSV, JSON, npy, HTML, Markdown)
    goes through here, so an interrupted run never leaves a half-written file
    under a final name. A full disk is reported as
    :class:`~sparselt.storage.errors.DiskFullError` naming ``path``.
    """
    from .storage.errors import no_space_is_clear

    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    with no_space_is_clear(path, f"writing {os.path.basename(path)!r}",
                           "finished work is kept: free some space and rerun the same command to resume"):
        descriptor, temporary = tempfile.mkstemp(dir=folder, prefix=".tmp-", suffix=os.path.basename(path))
        os.close(descriptor)
        try:
            write(temporary)
            handle = os.open(temporary, os.O_RDONLY)
            try:
                os.fsync(handle)
            finally:
                os.close(handle)
            os.chmod(temporary, 0o666 & ~_umask())  # mkstemp makes 0600; give the usual permissions
            os.replace(temporary, path)
        except BaseException:
            if os.path.exists(temporary):
                os.unlink(temporary)
            raise


def atomic_write_bytes(path, data):
    """Write ``data`` to ``path`` atomically (:func:`atomic_write`)."""

    def write(temporary):
        with open(temporary, "wb") as handle:
            handle.write(data)

    atomic_write(path, write)


def atomic_save_npy(path, array):
    """Write ``array`` as a ``.npy`` file atomically."""
    import numpy as np

    buffer = io.BytesIO()
    np.save(buffer, array)
    atomic_write_bytes(path, buffer.getvalue())


def _umask():
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_json(path, record):
    """Write a JSON record atomically, pretty-printed."""
    atomic_write_bytes(path, (json.dumps(record, indent=2, sort_keys=False, default=_json_default) + "\n").encode())


def read_json(path):
    """Read a JSON file; a corrupt one is a ValueError naming the file and the position."""
    with open(path, encoding="utf-8") as handle:
        try:
            return json.load(handle)
        except json.JSONDecodeError as error:
            raise ValueError(f"{path!r} is not valid JSON ({error.msg} at line {error.lineno}, column {error.colno}); "
                             "the file is corrupt: restore it or remove the folder") from None


def format_bytes(count):
    """A byte count for people: '512 B', '3.4 MB', '1.2 GB' (never '0.0 GB')."""
    count = float(count)
    for unit in ("B", "kB", "MB", "GB", "TB"):
        if abs(count) < 1000 or unit == "TB":
            return f"{count:.0f} {unit}" if unit == "B" else f"{count:.1f} {unit}"
        count /= 1000
    return f"{count:.1f} TB"


def _json_default(value):
    if hasattr(value, "tolist"):
        return value.tolist()
    if hasattr(value, "__dict__"):
        return vars(value)
    raise TypeError(f"cannot store {type(value).__name__} in JSON")
