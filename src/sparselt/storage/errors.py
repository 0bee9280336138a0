"""What went wrong on disk, in words: operating-system errors and a full disk, named by path.

The operating system reports some failures without a path (a full disk met
while writing an open file) and others on a path the user never typed (a
folder sparselt creates inside the one given). Every message sparselt prints
for them comes from here: :func:`os_error_reason` says what failed on which
path (and which part of the path is in the way), and :class:`no_space_is_clear`
turns a full disk into a :class:`DiskFullError` naming the path being written.
:mod:`sparselt.storage.cache` adds, for the cache, the variable that chose
its folder.
"""

from __future__ import annotations

import errno
import os
import shutil

#: The errors a full disk (or a quota, or a file-size limit) raises.
NO_SPACE_ERRORS = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)

#: The hint each common error adds (what it means for the user).
OS_ERROR_HINTS = {
    errno.EROFS: "the file system is read-only",
    errno.ENOSPC: "the disk is full",
    errno.EDQUOT: "the disk quota is used up",
    errno.EFBIG: "the file is larger than this system allows",
    errno.ENOTDIR: "a part of the path is a file, not a folder",
    errno.EISDIR: "the path is a folder, not a file",
    errno.EACCES: "no permission to write there",
    errno.EPERM: "no permission to write there",
    errno.ELOOP: "the path is a symbolic-link loop",
}


class DiskFullError(RuntimeError):
    """The device holding a store or a folder ran out of space; the run resumes once space is freed.

    Attributes
    ----------
    path : str or None
        The path that was being written.
    """

    def __init__(self, message, path=None):
        super().__init__(message)
        self.path = path


def blocking_file(path):
    """The deepest existing part of ``path`` when it is a file, not a folder (what makes ``path`` impossible), else
    ``None``."""
    probe = os.path.abspath(os.fspath(path))
    while True:
        if os.path.lexists(probe):
            return probe if os.path.exists(probe) and not os.path.isdir(probe) else None
        parent = os.path.dirname(probe)
        if parent == probe:
            return None
        probe = parent


def os_error_reason(error, path=None):
    """What an operating-system error means, in one phrase that names the path (``path`` when the error has none).

    Parameters
    ----------
    error : OSError
    path : str, optional
        The path being written, for errors the operating system reports
        without one (a full disk met while writing an open file).

    Returns
    -------
    str
        ``'<reason>: <path> (<hint>)'``, e.g. ``"Not a directory: '/a/file/sub' ('/a/file' is a file, not a
        folder)"`` (:func:`os_error_hint`); without any path, ``'<reason> (<hint>)'``.
    """
    target = error.filename if error.filename is not None else path
    reason = error.strerror or type(error).__name__
    if is_link_loop(target):
        reason = os.strerror(errno.ELOOP)
    hint = os_error_hint(error, path)
    where = f": {os.fspath(target)!r}" if target is not None else ""
    return f"{reason}{where}" + (f" ({hint})" if hint and hint != reason else "")


def os_error_hint(error, path=None):
    """What an operating-system error means for the user, for a sentence that already names the path: the file in
    the way, a symbolic-link loop, a read-only file system, a full disk with its free space; else the system's
    reason."""
    target = error.filename if error.filename is not None else path
    if target is not None and error.errno in (errno.ENOTDIR, errno.EEXIST, errno.ENOENT):
        if is_link_loop(target):
            return OS_ERROR_HINTS[errno.ELOOP]
        blocker = blocking_file(target)
        if blocker is not None and os.path.abspath(os.fspath(target)) != blocker:
            return f"{blocker!r} is a file, not a folder"
    hint = OS_ERROR_HINTS.get(error.errno) or error.strerror or type(error).__name__
    if error.errno in NO_SPACE_ERRORS and target is not None:
        hint = f"{hint}: {_free_space(target)}"
    return hint


def is_link_loop(path):
    """Whether ``path`` (or a part of it) is a symbolic-link loop."""
    if path is None:
        return False
    try:
        os.stat(path)
    except OSError as error:
        return error.errno == errno.ELOOP
    return False


def output_path_problem(path):
    """Why ``path`` cannot be an output folder, as the end of a sentence naming it, or ``None``.

    A symbolic-link loop, a broken symbolic link, an existing file, or a file
    in the way of creating it (``'/a/file/out'``): each says what to do.
    """
    path = os.fspath(path)
    if is_link_loop(path):
        return "is a symbolic link loop; choose another --out"
    if os.path.lexists(path) and not os.path.exists(path):
        return "is a broken symbolic link; choose another --out"
    if os.path.exists(path) and not os.path.isdir(path):
        return "is an existing file, not a folder; choose another --out"
    blocker = blocking_file(path)
    if blocker is not None:
        return f"cannot be created: {blocker!r} is a file, not a folder; choose another --out"
    return None


def _free_space(path):
    probe = os.path.abspath(os.fspath(path))
    while not os.path.exists(probe) and os.path.dirname(probe) != probe:
        probe = os.path.dirname(probe)
    try:
        return f"{shutil.disk_usage(probe).free} bytes free"
    except OSError:
        return "free space unknown"


def no_space_cause(error):
    """The full-disk :class:`OSError` in the chain of causes of ``error``, or ``None``."""
    seen = set()
    while error is not None and id(error) not in seen:
        if isinstance(error, OSError) and error.errno in NO_SPACE_ERRORS:
            return error
        seen.add(id(error))
        error = error.__cause__ or error.__context__
    return None


class no_space_is_clear:
    """Context manager: a full disk (ENOSPC, EDQUOT, EFBIG) becomes a :class:`DiskFullError` naming ``path``.

    Parameters
    ----------
    path : str
        What is being written (a store, a folder, a file).
    action : str
        What was being done, for the message ('writing chunk 3').
    remedy : str, optional
        What to do (default: free some space and rerun to resume).
    """

    def __init__(self, path, action,
                 remedy="finished chunks are kept: free some space and rerun the same command to resume"):
        self.path, self.action, self.remedy = os.fspath(path), action, remedy

    def __enter__(self):
        return self

    def __exit__(self, kind, error, traceback):
        if error is None:
            return False
        cause = no_space_cause(error)
        if cause is None:
            return False
        raise DiskFullError(
            f"no space left on the device holding {self.path!r} while {self.action} ({os.strerror(cause.errno)}, "
            f"{_free_space(self.path)}); {self.remedy}", path=self.path) from None


def caused_by_interrupt(error):
    """Whether ``error`` is a Ctrl-C: a KeyboardInterrupt, or an error with one in its chain of causes.

    ``drjit.custom`` wraps a KeyboardInterrupt raised in ``mi.render``'s Python part in a RuntimeError; a Ctrl-C
    during a Mitsuba render cancels the render with a RuntimeError, and the KeyboardInterrupt then fires with that
    error as its context. Both are interruptions, not failures.
    """
    seen = set()
    while error is not None and id(error) not in seen:
        if isinstance(error, KeyboardInterrupt):
            return True
        seen.add(id(error))
        error = error.__cause__ or error.__context__
    return False


__all__ = ["DiskFullError", "NO_SPACE_ERRORS", "OS_ERROR_HINTS", "blocking_file", "caused_by_interrupt",
           "is_link_loop", "no_space_cause", "no_space_is_clear", "os_error_hint", "os_error_reason",
           "output_path_problem"]
