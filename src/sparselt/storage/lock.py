"""One writer per signal store: an exclusive ``flock`` on a lock file inside the store.

The lock is the kernel's (``fcntl.flock``), so it dies with its process: a
run killed by SIGKILL leaves a lock file that the next run takes over without
any guessing about whether its holder is alive. The file records the holder's
PID, host, start time and command, so a refused second writer can say who
holds the store. On release the file is removed while still locked; a
process that opened it just before checks, after locking, that the path still
names the file it locked (the classic inode check), so two runs can never both
believe they hold the store.

A lock that cannot be taken leaves nothing behind: a lock file this process
could not fill in (a full disk) is removed, and the failure names the folder
(:class:`~sparselt.storage.errors.DiskFullError`).
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import os
import socket
import sys
from datetime import datetime, timezone

from .errors import no_space_is_clear

LOCK_FILE = ".sparselt.lock"
#: What to do when a full disk leaves no room for the lock's record.
LOCK_REMEDY = "nothing was changed there: free some space, or choose another --out on a disk with room"


class StoreLockedError(RuntimeError):
    """Another process is writing this store."""


def _holder_record():
    return {"pid": os.getpid(), "host": socket.gethostname(),
            "since": datetime.now(timezone.utc).isoformat(timespec="seconds"), "command": " ".join(sys.argv)}


def _read_holder(descriptor):
    try:
        os.lseek(descriptor, 0, os.SEEK_SET)
        text = os.read(descriptor, 1 << 16).decode("utf-8", "replace")
        return json.loads(text) if text.strip() else None
    except (OSError, ValueError):
        return None


def _describe(holder):
    if not holder:
        return "another process (it has not recorded itself yet)"
    return (f"PID {holder.get('pid')} on host {holder.get('host')!r} since {holder.get('since')} "
            f"(command: {holder.get('command') or 'unknown'})")


def _process_alive(pid):
    try:
        os.kill(int(pid), 0)
    except ProcessLookupError:
        return False
    except (PermissionError, ValueError, TypeError, OverflowError):
        return True
    return True


def check_unlocked(folder, what="signal store"):
    """Raise :class:`StoreLockedError` if a live process holds ``folder``'s lock (changes nothing).

    ``what`` names the folder in the message ('signal store', 'comparison folder', ...).
    """
    path = os.path.join(os.fspath(folder), LOCK_FILE)
    try:
        descriptor = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        fcntl.flock(descriptor, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except OSError as error:
        if error.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
            raise StoreLockedError(_locked_message(folder, _read_holder(descriptor), what)) from None
        raise
    finally:
        os.close(descriptor)


def _locked_message(folder, holder, what="signal store"):
    return (f"{what} {os.fspath(folder)!r} is being written by {_describe(holder)}; "
            "wait for that run to finish or stop it (a killed run's lock is taken over automatically)")


class StoreLock:
    """Exclusive lock on a signal store folder (context manager).

    Parameters
    ----------
    folder : str
        The store folder; it must exist.
    what : str, optional
        What the folder is, for messages (default 'signal store').

    Attributes
    ----------
    previous_holder : dict or None
        The record left by a dead holder whose lock was taken over (a run that
        was killed), else ``None``.
    """

    def __init__(self, folder, what="signal store"):
        self.folder = os.fspath(folder)
        self.what = what
        self.path = os.path.join(self.folder, LOCK_FILE)
        self._descriptor = None
        self.previous_holder = None

    def acquire(self):
        """Take the lock or raise :class:`StoreLockedError` naming its holder.

        Raises
        ------
        StoreLockedError
            A live process holds the lock.
        DiskFullError
            No room for the holder's record; the lock file is removed again.
        """
        with no_space_is_clear(self.folder, f"taking its lock ({LOCK_FILE!r})", LOCK_REMEDY):
            return self._acquire()

    def _acquire(self):
        for _ in range(100):
            descriptor = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(descriptor, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError as error:
                holder = _read_holder(descriptor)
                os.close(descriptor)
                if error.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                    raise StoreLockedError(_locked_message(self.folder, holder, self.what)) from None
                raise
            try:
                same_file = os.fstat(descriptor).st_ino == os.stat(self.path).st_ino
            except FileNotFoundError:
                same_file = False
            if not same_file:  # the holder removed the file between our open and our lock: try again
                os.close(descriptor)
                continue
            previous = _read_holder(descriptor)
            if previous and previous.get("pid") != os.getpid():
                # flock is free, so its holder is gone; say so when we can tell.
                if previous.get("host") == socket.gethostname() and not _process_alive(previous.get("pid", -1)):
                    self.previous_holder = previous
            try:
                os.ftruncate(descriptor, 0)
                os.lseek(descriptor, 0, os.SEEK_SET)
                os.write(descriptor, (json.dumps(_holder_record()) + "\n").encode())
                os.fsync(descriptor)
            except BaseException:
                with contextlib.suppress(OSError):  # we hold it: an empty lock file must not stay behind
                    os.unlink(self.path)
                os.close(descriptor)
                raise
            self._descriptor = descriptor
            return self
        raise StoreLockedError(f"could not lock {self.path!r}: it keeps being replaced by another process")

    def release(self):
        """Remove the lock file and unlock; safe to call twice."""
        if self._descriptor is None:
            return
        try:
            os.unlink(self.path)
        except FileNotFoundError:
            pass
        finally:
            os.close(self._descriptor)  # closing releases the flock
            self._descriptor = None

    @property
    def held(self):
        return self._descriptor is not None

    def __enter__(self):
        return self.acquire()

    def __exit__(self, *exception):
        self.release()
