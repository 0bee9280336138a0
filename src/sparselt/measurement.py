"""Measuring: best-of wall time, process and system memory (Linux ``/proc``), phase timers, progress bars."""

from __future__ import annotations

import os
import time


def best_time(function, repeats, *, warmup=True):
    """Smallest wall time of ``repeats`` calls of ``function()`` (seconds), after one untimed call.

    The warm-up absorbs one-off costs (JIT compilation, FFT plans, page faults).
    """
    if warmup:
        function()
    best = float("inf")
    for _ in range(max(1, int(repeats))):
        start = time.perf_counter()
        function()
        best = min(best, time.perf_counter() - start)
    return best


def status_bytes(field_name):
    """A size field of ``/proc/self/status`` in bytes, e.g. ``'VmRSS'`` (resident) or ``'VmHWM'`` (peak)."""
    with open("/proc/self/status", encoding="ascii") as handle:
        for line in handle:
            if line.startswith(field_name + ":"):
                return int(line.split()[1]) * 1024
    raise OSError(f"/proc/self/status has no {field_name} line")


def reset_peak():
    """Reset ``VmHWM`` to the current ``VmRSS`` (Linux >= 4.0); ``False`` where not allowed."""
    try:
        with open("/proc/self/clear_refs", "w", encoding="ascii") as handle:
            handle.write("5")
    except OSError:
        return False
    return True


def meminfo_bytes(field_name):
    """A field of ``/proc/meminfo`` in bytes (``'MemAvailable'``, ``'MemTotal'``), or None where unreadable."""
    try:
        with open("/proc/meminfo", encoding="ascii") as handle:
            for line in handle:
                if line.startswith(field_name + ":"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return None


def available_memory():
    """Bytes of memory available to a new allocation (``MemAvailable``; free pages where unreadable)."""
    available = meminfo_bytes("MemAvailable")
    if available is None:
        available = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    return available


class PhaseTimer:
    """Wall seconds per phase: ``with timer('sampling'): ...`` adds the block's time to that phase.

    Used by the recovery algorithms (their result records' ``time``) and by the
    comparison methods (``sampling``, ``reconstruction``, ``integration``, ``other``).
    """

    def __init__(self, phases):
        self.seconds = {phase: 0.0 for phase in phases}
        self._phase = None

    def __call__(self, phase):
        if phase not in self.seconds:
            raise ValueError(f"unknown phase {phase!r}; phases are {', '.join(self.seconds)}")
        self._phase = phase
        return self

    def __enter__(self):
        self._start = time.perf_counter()
        return self

    def __exit__(self, *exception):
        self.seconds[self._phase] += time.perf_counter() - self._start
        return False


def progress_bar(enabled, *, total, description, unit, iterable=None, initial=0):
    """A tqdm bar on standard error, or None (or the bare iterable) when not ``enabled``: the one helper."""
    if not enabled:
        return iterable
    from tqdm.auto import tqdm

    return tqdm(iterable, total=total, desc=description, unit=unit, unit_scale=unit != "piece", initial=initial,
                dynamic_ncols=True)
