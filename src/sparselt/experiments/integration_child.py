"""The child process of the integration benchmark: one ``(s, method)`` measured in a fresh Python process.

Thesis section 4.3 compares the time and memory of the integration methods.
Each ``(s, method)`` runs in a fresh Python process
(``python -m sparselt.experiments.integration_child TASK``), so the peak is
that method's own, including memory that ducc0 and numpy allocate in C.

How parent and child talk
-------------------------
The parent (:func:`run_child`) passes the task as one JSON argument:
``size``, ``method``, ``seed``, ``density``, ``minimum_reaching``, ``repeats``
and ``check``. The child prints one line, ``RESULT_PREFIX`` followed by a
JSON record, to standard output and exits with status 0; on any exception it
prints the traceback to standard error and exits with status 1. The parent
gets the record, or a reason: a timeout, a signal (9: killed, out of
memory?), or the last line of the child's standard error.

How memory is measured
----------------------
The child

1. builds the representation in O(K) memory
   (:func:`~sparselt.experiments.integration_signal.thesis_signal`),
2. runs a tiny warm-up integration with the same method (thread pool, lazy
   imports, FFT plan caches),
3. resets the kernel's high-water mark (``/proc/self/clear_refs``, value 5)
   where the kernel allows it, and reads its resident set size ``VmRSS`` from
   ``/proc/self/status`` as the baseline,
4. runs ``integrate`` once and reports ``VmHWM - baseline`` as the peak, then
   repeats the call for timing (best of the runs),
5. reports how many coefficients reach the image, in the measured signal and
   in the uniform draw it was made from, and the largest value of the image
   the timed call returned (zero: the method was timed integrating nothing),
6. when the task asks for it, checks the method against ``'convolution'``.

References
----------
Thesis chapter 4, section 4.3 (methodology), Table 4.1.
"""

from __future__ import annotations

import gc
import json
import subprocess
import sys
import time
import traceback

import numpy as np

from ..fourier.integration import integrate
from ..measurement import reset_peak, status_bytes
from .integration_signal import KEEP_AXES, agreement_signal, contributing_coefficients, thesis_signal
from .isolation import child_environment, describe_exit, exit_cause

CHILD_MODULE = "sparselt.experiments.integration_child"
RESULT_PREFIX = "INTEGRATION-BENCHMARK-RESULT "
REPEAT_SECONDS = 30.0
CHILD_TIMEOUT_SECONDS = 1800


def measure_in_this_process(task):
    """Run one measurement in this process (the child).

    Parameters
    ----------
    task : dict
        ``size``, ``method``, ``seed``, ``density``, ``minimum_reaching`` (see
        :func:`~sparselt.experiments.integration_signal.thesis_signal`),
        ``repeats`` (timed calls at most; fewer once they have taken
        ``REPEAT_SECONDS``) and ``check`` (compare with ``'convolution'``).

    Returns
    -------
    dict
        JSON-able: ``seconds`` (every timed call), ``peak_bytes``,
        ``baseline_bytes``, ``preexisting_bytes`` (``VmHWM - VmRSS`` before
        the call), ``peak_reset``, ``contributing_coefficients`` (reaching
        the image), ``uniform_contributing_coefficients`` (reaching it in the
        uniform draw before ``minimum_reaching`` moved any), ``image_max``
        (largest ``|value|`` of the timed call's image), ``check_error``
        (``None`` when not checked) and ``output_shape``.
    """
    size, method, seed = int(task["size"]), task["method"], int(task["seed"])
    density, repeats = float(task["density"]), int(task["repeats"])
    minimum_reaching = int(task["minimum_reaching"])
    integrate(thesis_signal(4, density=0.05, seed=seed), KEEP_AXES, method)  # warm-up
    representation = thesis_signal(size, density=density, seed=seed, minimum_reaching=minimum_reaching)
    gc.collect()
    reset = reset_peak()
    baseline = status_bytes("VmRSS")
    preexisting = status_bytes("VmHWM") - baseline
    start = time.perf_counter()
    result = integrate(representation, KEEP_AXES, method)
    seconds = [time.perf_counter() - start]
    peak = status_bytes("VmHWM") - baseline
    while len(seconds) < repeats and sum(seconds) < REPEAT_SECONDS:
        start = time.perf_counter()
        integrate(representation, KEEP_AXES, method)
        seconds.append(time.perf_counter() - start)
    check_error = None
    if task["check"]:
        # The measured signal against 'convolution', relative to one coefficient's contribution max|c| / N ...
        reference = integrate(representation, KEEP_AXES, "convolution")
        scale = float(np.abs(representation.values).max()) / representation.size
        measured_error = float(np.abs(result - reference).max()) / scale
        # ... and a signal with on-plane coefficients, relative to its largest output.
        checked = agreement_signal(representation, seed)
        reference = integrate(checked, KEEP_AXES, "convolution")
        check_error = max(measured_error, float(np.abs(integrate(checked, KEEP_AXES, method) - reference).max())
                          / float(np.abs(reference).max()))
    return {
        "seconds": seconds,
        "peak_bytes": int(peak),
        "baseline_bytes": int(baseline),
        "preexisting_bytes": int(preexisting),
        "peak_reset": reset,
        "contributing_coefficients": contributing_coefficients(representation),
        "uniform_contributing_coefficients": contributing_coefficients(
            thesis_signal(size, density=density, seed=seed, minimum_reaching=0)),
        "image_max": float(np.abs(result).max()),
        "check_error": check_error,
        "output_shape": list(result.shape),
    }


def child_main(arguments):
    """The child's entry point: measure the task in ``arguments[0]`` and print the record.

    Parameters
    ----------
    arguments : list of str
        The command-line arguments; the first is the task as JSON.

    Returns
    -------
    int
        Exit status: 0 after printing the record, 1 after printing the
        traceback of any failure (the parent records it).
    """
    try:
        record = measure_in_this_process(json.loads(arguments[0]))
    except Exception:  # report any failure to the parent, which records it
        traceback.print_exc()
        return 1
    sys.stdout.write(RESULT_PREFIX + json.dumps(record) + "\n")
    sys.stdout.flush()
    return 0


def run_child(task, module=CHILD_MODULE):
    """Measure ``task`` in a fresh process (the parent's side).

    Parameters
    ----------
    task : dict
        The task passed to :func:`measure_in_this_process`.
    module : str, optional
        The module the child runs with ``python -m``.

    Returns
    -------
    tuple
        ``(record, None)`` with the child's record, or ``(None, reason)``
        when the child timed out, was ended by a signal or failed.
    """
    command = [sys.executable, "-m", module, json.dumps(task)]
    try:
        completed = subprocess.run(command, capture_output=True, text=True, timeout=CHILD_TIMEOUT_SECONDS,
                                   env=child_environment())
    except subprocess.TimeoutExpired:
        return None, f"timed out after {CHILD_TIMEOUT_SECONDS} s"
    for line in completed.stdout.splitlines():
        if line.startswith(RESULT_PREFIX) and completed.returncode == 0:
            return json.loads(line[len(RESULT_PREFIX):]), None
    if completed.returncode < 0:
        cause = exit_cause(completed.returncode)
        return None, f"child process ended by {describe_exit(completed.returncode)}" + (f": {cause}" if cause else "")
    lines = [line for line in completed.stderr.strip().splitlines() if line.strip()]
    return None, f"child process failed (exit {completed.returncode}): {lines[-1] if lines else 'no message'}"


if __name__ == "__main__":
    sys.exit(child_main(sys.argv[1:]))
