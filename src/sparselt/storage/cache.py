"""sparselt's cache: ``$SPARSELT_CACHE`` (default ``~/.cache/sparselt``), one sub-folder per use.

The reference renders of every comparison (``references/``, see
:func:`sparselt.rendering.baseline.cached_reference`) and the procedural
scenes' meshes (``meshes/``) are cached here. The user never types these
paths, so every failure to use them says which variable chose the folder,
its value and what to do (:func:`cache_failure`), never just the operating
system's words about a path the user has not seen.
"""

from __future__ import annotations

import contextlib
import errno
import os
import shlex

from .errors import DiskFullError, no_space_cause, os_error_hint

#: The environment variable that chooses the cache folder.
CACHE_VARIABLE = "SPARSELT_CACHE"


class CacheError(RuntimeError):
    """The cache folder cannot be used; the message names :data:`CACHE_VARIABLE`, its value and the fix."""


def cache_root():
    """The cache folder: ``$SPARSELT_CACHE``, or ``~/.cache/sparselt`` when it is unset or empty."""
    return os.environ.get(CACHE_VARIABLE) or os.path.join(os.path.expanduser("~"), ".cache", "sparselt")


def cache_directory(name):
    """The cache's sub-folder ``name`` ('references', 'meshes'), not created."""
    return os.path.join(cache_root(), name)


def cache_setting():
    """Where the cache folder comes from, for messages: ``SPARSELT_CACHE=<value>`` or the default."""
    value = os.environ.get(CACHE_VARIABLE)
    if value:
        return f"{CACHE_VARIABLE}={shlex.quote(value)}"
    return f"{CACHE_VARIABLE} is not set, so the cache is the default {cache_root()!r}"


def _under_cache_root(path):
    root = os.path.abspath(cache_root())
    path = os.path.abspath(os.fspath(path))
    return path == root or path.startswith(root.rstrip(os.sep) + os.sep)


def cache_failure(error, path, action="use"):
    """The :class:`CacheError` for ``error`` (an :class:`OSError` or a :class:`DiskFullError`) met on the cache
    path ``path``: one line naming the folder, what went wrong, the variable and its value, and what to do.

    A folder that is not under :func:`cache_root` (one given to a function as
    ``cache_directory``) is named as such, without the variable.
    """
    path = os.fspath(path)
    variable = _under_cache_root(path)
    setting = cache_setting() if variable else "given as cache_directory"
    full = isinstance(error, DiskFullError) or no_space_cause(error) is not None
    if isinstance(error, OSError):
        hint = os_error_hint(error, path)
        if error.filename is not None and error.filename != path and hint in (error.strerror, None):
            hint = f"{hint}: {error.filename!r}"
    else:
        hint = "no space left on the device" if full else str(error)
    if full:
        fix = (f"free some space there, or set {CACHE_VARIABLE} to a folder on another disk, then rerun the same "
               "command (finished work is kept)" if variable
               else "free some space there, or give a folder on another disk, then rerun (finished work is kept)")
        if isinstance(error, DiskFullError) and error.path:
            return CacheError(f"no space left for the cache on the device holding {error.path!r} ({setting}); {fix}")
        return CacheError(f"no space left for the cache folder {path!r} ({hint}; {setting}); {fix}")
    if variable:
        fix = (f"set {CACHE_VARIABLE} to a folder you can write (or unset it to use ~/.cache/sparselt)"
               if os.environ.get(CACHE_VARIABLE) else f"set {CACHE_VARIABLE} to a folder you can write")
    else:
        fix = "give a folder you can write"
    return CacheError(f"cannot {action} the cache folder {path!r}: {hint} ({setting}); {fix}")


@contextlib.contextmanager
def cache_errors(path, action="use"):
    """Context manager: an :class:`OSError` or a full disk inside becomes :func:`cache_failure`'s
    :class:`CacheError` for the cache folder ``path``."""
    try:
        yield
    except CacheError:
        raise
    except (OSError, DiskFullError) as error:
        raise cache_failure(error, path, action) from None


def usable_cache_directory(path):
    """Create the cache folder ``path`` if needed and check that it can be written; return it.

    Called before any expensive work whose result goes into the cache, so a
    cache that cannot be used stops the run before it starts.

    Raises
    ------
    CacheError
        The folder cannot be created (a file in the way, a read-only or
        virtual file system, no permission, a full disk) or written.
    """
    path = os.fspath(path)
    with cache_errors(path, "create"):
        os.makedirs(path, exist_ok=True)
    if not os.access(path, os.W_OK | os.X_OK):
        code = errno.EROFS if _read_only(path) else errno.EACCES
        raise cache_failure(OSError(code, os.strerror(code)), path, "write")
    return path


def _read_only(path):
    try:
        return bool(os.statvfs(path).f_flag & os.ST_RDONLY)
    except OSError:
        return False


__all__ = ["CACHE_VARIABLE", "CacheError", "cache_directory", "cache_errors", "cache_failure", "cache_root",
           "cache_setting", "usable_cache_directory"]
