"""One piece of work in a fresh Python process, so that a crash in native code ends that piece alone (issue 37).

A segmentation fault in the renderer or in a compiled kernel ends the process
it happens in, with no Python exception to catch: in the sixteenth session
Mitsuba 3.9 read one past a B-spline curve's segment table, and the whole
``suite`` run ended with nothing recorded for any scene after it. A suite now
runs each scene's comparison through :func:`run_in_child`: the crash ends the
child, and the parent raises :class:`ChildCrashed`, which the suite records
as that scene's reason for not being compared.

How parent and child talk
-------------------------
The parent pickles the call (a module-level function, its arguments) into a
temporary folder beside what the child needs to resolve it the way the
parent would: the parent's ``sys.path``, the modules of every method
registered outside sparselt (``--plugin`` modules, methods a script
registered), the command line the outputs record, the Mitsuba variant and
the renderer's and numba's thread counts. The child
(``python -m sparselt.experiments.isolation TASK RESULT``) turns on
``faulthandler`` (every thread's stack on standard error if it crashes),
restores that state, makes the call, and pickles ``("value", result)`` or
``("error", exception)`` into ``RESULT``. Standard output and standard error
are the parent's, so progress bars and error messages appear as before. A
child that ends without a result (a signal, or ``os._exit``) is a
:class:`ChildCrashed`; an exception in the child is raised again in the
parent, with the child's traceback as its note.

:mod:`sparselt.experiments.integration_child` is another child process, with
a protocol of its own: it measures the child's memory peak, which needs a
process per measurement rather than per piece of work.
"""

from __future__ import annotations

import faulthandler
import os
import pickle
import signal
import subprocess
import sys
import tempfile
import traceback

CHILD_MODULE = "sparselt.experiments.isolation"
#: Seconds an interrupted parent waits for its child to end on its own (a Ctrl-C at the terminal reaches both).
OWN_END_SECONDS = 5.0
#: Seconds the parent then gives the child it interrupted to end (its finished work kept) before killing it.
INTERRUPT_GRACE_SECONDS = 30.0


class ChildCrashed(RuntimeError):
    """The child process ended without a result: killed by a signal (``signal_number``) or exited with a status.

    Attributes
    ----------
    returncode : int
        The child's exit status as :class:`subprocess.Popen` reports it (``-N``: signal ``N``).
    """

    def __init__(self, message, returncode):
        super().__init__(message)
        self.returncode = returncode

    def __reduce__(self):
        return type(self), (str(self), self.returncode)

    @property
    def signal_number(self):
        """The signal that ended the child, or None."""
        return -self.returncode if self.returncode < 0 else None


def describe_exit(returncode):
    """``'signal 11 (SIGSEGV)'`` or ``'exit status 3'``: how a process ended, in words."""
    if returncode < 0:
        try:
            name = signal.Signals(-returncode).name
        except ValueError:
            name = "unknown signal"
        return f"signal {-returncode} ({name})"
    return f"exit status {returncode}"


#: Signals of a crash in native code: a bad memory access, an illegal instruction, an arithmetic fault, an abort.
CRASH_SIGNALS = (signal.SIGSEGV, signal.SIGBUS, signal.SIGILL, signal.SIGFPE, signal.SIGABRT)


def exit_cause(returncode):
    """What a process's end by ``returncode`` most likely means, in words, or ``''`` where it says nothing more."""
    if returncode < 0 and -returncode in CRASH_SIGNALS:
        return "a crash in native code (the renderer or a compiled kernel; its stack is on standard error)"
    if returncode == -signal.SIGKILL:
        return "killed (by the system when memory runs out, or by a user)"
    return ""


def child_environment():
    """This process's environment with the folder holding the ``sparselt`` package it imported first on
    ``PYTHONPATH``: a child started with ``python -m sparselt...`` imports the same package (also the
    integration benchmark's child, :mod:`sparselt.experiments.integration_child`).

    Returns
    -------
    dict
        Environment variables for the child process.
    """
    environment = dict(os.environ)
    source = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    environment["PYTHONPATH"] = os.pathsep.join(filter(None, [source, environment.get("PYTHONPATH")]))
    return environment


def _thread_counts():
    """The renderer's and numba's thread counts of this process, where they are started (else None)."""
    renderer = numba_threads = None
    if "drjit" in sys.modules:
        renderer = int(sys.modules["drjit"].thread_count())
    if "numba" in sys.modules:
        numba_threads = int(sys.modules["numba"].get_num_threads())
    return renderer, numba_threads


def _state(threads):
    """What the child restores before the call (see the module docstring)."""
    from ..methods import plugin_modules
    from ..provenance import recorded_command

    renderer, numba_threads = _thread_counts()
    if threads is not None:
        renderer = numba_threads = int(threads)
    runtime = sys.modules.get("sparselt.rendering.mitsuba.runtime")
    variant = runtime.mi.variant() if runtime is not None and runtime.mi is not None else None
    return {"sys_path": list(sys.path), "modules": list(plugin_modules()), "command": recorded_command(),
            "variant": variant, "renderer_threads": renderer, "numba_threads": numba_threads}


def run_in_child(function, *arguments, child_threads=None, **keywords):
    """Call ``function(*arguments, **keywords)`` in a fresh Python process and return its result.

    Parameters
    ----------
    function : callable
        A module-level function (pickled by name).
    *arguments, **keywords
        Its arguments (pickled).
    child_threads : int, optional
        The renderer's and numba's thread count in the child (default: this process's).

    Returns
    -------
    object
        What ``function`` returned.

    Raises
    ------
    ChildCrashed
        The child ended without a result (a signal such as SIGSEGV, or an exit without one).
    Exception
        What ``function`` raised in the child, raised again here (its traceback attached as a note).
    KeyboardInterrupt
        Interrupted while waiting: the child is given :data:`OWN_END_SECONDS`
        to end on its own (a Ctrl-C at the terminal reached it too), then
        interrupted and given :data:`INTERRUPT_GRACE_SECONDS`, then killed.
    """
    call = pickle.dumps((function, arguments, keywords), protocol=pickle.HIGHEST_PROTOCOL)
    task = {"state": _state(child_threads), "call": call}
    with tempfile.TemporaryDirectory(prefix="sparselt-child-") as directory:
        task_path, result_path = os.path.join(directory, "task.pickle"), os.path.join(directory, "result.pickle")
        with open(task_path, "wb") as handle:
            pickle.dump(task, handle, protocol=pickle.HIGHEST_PROTOCOL)
        process = subprocess.Popen([sys.executable, "-m", CHILD_MODULE, task_path, result_path],
                                   env=child_environment(), stdin=subprocess.DEVNULL)
        try:
            returncode = process.wait()
        except BaseException:
            _stop(process)
            raise
        if not os.path.exists(result_path):
            raise ChildCrashed(f"the child process ended with {describe_exit(returncode)} and no result",
                               returncode)
        with open(result_path, "rb") as handle:
            outcome, value = pickle.load(handle)
    if outcome == "value":
        return value
    raise value


def _stop(process):
    """End ``process`` after its parent was interrupted: a Ctrl-C at the terminal reached it too, so first let it
    end on its own (its Ctrl-C handling keeps finished work); else interrupt it; kill it if it still runs."""
    for send in (None, signal.SIGINT):
        if send is not None:
            process.send_signal(send)
        try:
            process.wait(timeout=OWN_END_SECONDS if send is None else INTERRUPT_GRACE_SECONDS)
            return
        except subprocess.TimeoutExpired:
            continue
    process.kill()
    process.wait()


def _restore(state):
    for path in reversed(state["sys_path"]):
        if path not in sys.path:
            sys.path.insert(0, path)
    from ..provenance import record_command

    record_command(state["command"])
    if state["variant"] is not None:
        from ..rendering.mitsuba.runtime import initialize

        initialize(state["variant"])
    if state["renderer_threads"] is not None:
        from ..rendering.mitsuba.runtime import set_thread_count

        set_thread_count(state["renderer_threads"])
    if state["numba_threads"] is not None:
        import numba

        numba.set_num_threads(min(state["numba_threads"], numba.config.NUMBA_NUM_THREADS))
    load_importable_plugins(state["modules"])


def load_importable_plugins(modules):
    """Import the plug-in ``modules`` another process had registered; one this process cannot import is reported
    on standard error and left out (the work may not need its methods; if it does, it says which is unknown)."""
    from ..methods import PluginError, load_plugins

    for module in modules:
        try:
            load_plugins([module])
        except PluginError as error:
            print(f"sparselt: plug-in module {module!r}, which the parent process had imported, is left out here: "
                  f"{error}", file=sys.stderr)


def _picklable(error):
    """``error`` if it survives pickling both ways, else a RuntimeError carrying its type and message."""
    try:
        pickle.loads(pickle.dumps(error))
        return error
    except Exception:  # noqa: BLE001  (any failure to pickle)
        return RuntimeError(f"{type(error).__name__}: {error}")


def child_main(task_path, result_path):
    """The child: restore the parent's state, make the call, write its outcome (see the module docstring)."""
    faulthandler.enable(file=sys.stderr, all_threads=True)
    signal.signal(signal.SIGINT, signal.default_int_handler)  # a parent that ignores Ctrl-C can still interrupt us
    with open(task_path, "rb") as handle:
        task = pickle.load(handle)
    try:
        _restore(task["state"])
        function, arguments, keywords = pickle.loads(task["call"])
        outcome = ("value", function(*arguments, **keywords))
    except KeyboardInterrupt:  # the parent was interrupted too and reports it; no traceback from here
        return 130
    except Exception as error:  # noqa: BLE001  (raised again in the parent)
        where = "".join(traceback.format_exception(error)).rstrip()
        error = _picklable(error)
        error.add_note("in the child process:\n" + where)
        outcome = ("error", error)
    temporary = result_path + ".partial"
    with open(temporary, "wb") as handle:
        pickle.dump(outcome, handle, protocol=pickle.HIGHEST_PROTOCOL)
    os.replace(temporary, result_path)
    return 0


if __name__ == "__main__":
    sys.exit(child_main(*sys.argv[1:3]))
