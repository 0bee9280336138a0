"""Issue 37: a call in a fresh Python process returns its value, raises its error, and reports a crash."""

import faulthandler
import os
import signal

import pytest

from sparselt.experiments.isolation import ChildCrashed, describe_exit, exit_cause, run_in_child


def test_the_childs_value_comes_back():
    assert run_in_child(os.path.join, "a", "b") == os.path.join("a", "b")
    assert run_in_child(os.getpid) != os.getpid()  # another process


def test_the_childs_error_is_raised_with_its_message_and_traceback():
    with pytest.raises(ValueError, match="invalid literal for int") as raised:
        run_in_child(int, "not a number")
    assert any("in the child process" in note for note in raised.value.__notes__)


def test_a_segmentation_fault_in_the_child_is_a_crash_naming_the_signal(capfd):
    with pytest.raises(ChildCrashed, match=r"signal 11 \(SIGSEGV\)") as raised:
        run_in_child(faulthandler._sigsegv)
    assert raised.value.signal_number == signal.SIGSEGV
    assert "Fatal Python error: Segmentation fault" in capfd.readouterr().err  # the child's stack, on stderr


def test_an_exit_without_a_result_is_a_crash_naming_its_status():
    with pytest.raises(ChildCrashed, match="exit status 3") as raised:
        run_in_child(os._exit, 3)
    assert raised.value.signal_number is None
    assert describe_exit(-9) == "signal 9 (SIGKILL)"
    assert "native code" in exit_cause(-11) and "memory" in exit_cause(-9) and exit_cause(3) == ""


def test_the_child_has_the_parents_thread_count_unless_told():
    from sparselt.rendering.mitsuba.runtime import initialize, thread_count

    initialize()
    assert run_in_child(thread_count) == thread_count()
    assert run_in_child(thread_count, child_threads=1) == 1


def test_an_interrupted_parent_interrupts_its_child():
    """Ctrl-C while waiting (here an alarm raising KeyboardInterrupt): the child gets SIGINT and ends at once."""
    import time

    def interrupt(number, frame):
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGALRM, interrupt)
    started = time.perf_counter()
    try:
        signal.setitimer(signal.ITIMER_REAL, 3.0)
        with pytest.raises(KeyboardInterrupt):
            run_in_child(time.sleep, 120)
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
    assert time.perf_counter() - started < 20  # not the sleep, not the grace period
