"""Measuring for benchmarks: best-of wall time, process memory (Linux ``/proc/self``)."""

from __future__ import annotations

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
