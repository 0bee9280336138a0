"""The contract every comparison method keeps, built-in or plug-in, checked the same way for all.

Two layers, after scikit-learn's ``check_estimator``:

:func:`check_result`
    What the harness checks of every run (:func:`~sparselt.methods.base.run_timed`:
    ``run(context, budget, timer)`` with a fresh timer, whose phases are the
    result's seconds) before it records it: a
    :class:`MethodResult` whose image has the output's shape, dtype float32
    and finite pixels, whose seconds are non-negative, finite and only of
    :data:`TIME_PHASES`, a non-negative integer of path samples and JSON-able
    details. Given the harness's own wall time of the run, time the method did
    not put in a phase is added to ``'other'``: a method cannot make itself
    faster by leaving time untimed.
:func:`check_method`
    What the contract test (``tests/test_method_contract.py``) runs over every
    registered method: its declared preconditions (but the kind) met by the test's context,
    :func:`check_result`, phases that add up to the run's wall time, the path samples it reports equal to those the renderer drew
    (counted in the renderer's one launch seam, :func:`~sparselt.rendering.mitsuba.count_samples`), the same image for the same
    seed, and options that survive a JSON round trip.

References
----------
Thesis 8.1.1 (equal time: every second and every sample counted).
scikit-learn's ``utils.estimator_checks`` (one suite over every estimator).
"""

from __future__ import annotations

import json
import math
import time

import numpy as np

from ..rendering.mitsuba.launch import count_samples
from .base import TIME_PHASES, MethodResult, collect_recent_garbage, run_timed, warm_up
from .options import resolve_options
from .preconditions import MethodSetup, SupportedKind

#: Untimed seconds a run may leave outside its phases before :func:`check_method` calls it a breach:
#: the harness's own bookkeeping around ``run`` (result construction, a return) stays well below.
UNTIMED_TOLERANCE_SECONDS = 0.05
UNTIMED_TOLERANCE_FRACTION = 0.1


def check_result(method, result, context, budget, *, wall_seconds=None):
    """Check one run's result; return its seconds per phase (every phase of :data:`TIME_PHASES` present).

    Parameters
    ----------
    method : Method
        The instance that ran (its :attr:`~sparselt.methods.base.Method.label` names it).
    result : object
        What ``method.run`` returned.
    context : ComparisonContext
        The run's context (its ``resolution`` is the image's size).
    budget : Budget
    wall_seconds : float, optional
        The harness's wall time of the run; time beyond the phases' sum is
        added to ``'other'``.

    Returns
    -------
    dict
        ``{phase: seconds}`` for every phase.

    Raises
    ------
    ValueError
        The message names the method, the budget and what is wrong.
    """
    where = f"method {method.label!r} at spp {budget.spp}, seed {budget.seed}"
    if not isinstance(result, MethodResult):
        raise ValueError(f"{where} returned {type(result).__name__}, not a sparselt.methods.MethodResult")
    width, height = context.resolution
    image = result.image
    if not isinstance(image, np.ndarray) or image.shape != (height, width, 3):
        shape = getattr(image, "shape", type(image).__name__)
        raise ValueError(f"{where} returned an image of shape {shape}; the comparison needs ({height}, {width}, 3) "
                         "(height, width, RGB)")
    if image.dtype != np.float32:
        raise ValueError(f"{where} returned an image of dtype {image.dtype}; the comparison needs float32")
    if not np.all(np.isfinite(image)):
        raise ValueError(f"{where} produced NaN or infinite pixels")
    if not isinstance(result.seconds, dict):
        raise ValueError(f"{where}: seconds must be a dict of phases ({', '.join(TIME_PHASES)})")
    unknown = sorted(set(result.seconds) - set(TIME_PHASES))
    if unknown:
        raise ValueError(f"{where} reports seconds for {unknown}; the phases are {', '.join(TIME_PHASES)}")
    seconds = {}
    for phase in TIME_PHASES:
        value = result.seconds.get(phase, 0.0)
        if isinstance(value, bool) or not isinstance(value, (int, float, np.floating)) or not math.isfinite(value) \
                or value < 0:
            raise ValueError(f"{where}: seconds[{phase!r}] must be a finite number >= 0, got {value!r}")
        seconds[phase] = float(value)
    samples = result.path_samples
    if isinstance(samples, bool) or not isinstance(samples, (int, np.integer)) or samples < 0:
        raise ValueError(f"{where}: path_samples must be an integer >= 0 (every path sample drawn), got {samples!r}")
    try:
        json.dumps(result.details)
    except (TypeError, ValueError) as error:
        raise ValueError(f"{where}: details must be JSON-able ({error})") from None
    if wall_seconds is not None:
        seconds["other"] += max(0.0, float(wall_seconds) - sum(seconds.values()))
    return seconds


def check_method(method, context, budget):
    """Run ``method`` twice at ``budget`` on ``context`` and check the whole contract.

    ``method`` is an instance (the estimator with its options); every path
    sample the renderer draws in a run is counted in its one launch seam
    (:func:`sparselt.rendering.mitsuba.count_samples`), the contract's witness.

    Returns
    -------
    dict
        ``result`` (the first :class:`MethodResult`), ``seconds`` (its
        phases, from :func:`check_result`), ``wall_seconds``, ``drawn`` (path
        samples the renderer drew in the first run).

    Raises
    ------
    AssertionError
        A breach of the contract, named.
    ValueError
        The context does not meet one of the method's declared preconditions.
    """
    options = method.options
    record = json.loads(json.dumps(options.record()))
    assert resolve_options(method.Options, record, grid_shape=context.grid_shape, owner=method.name) == options, (
        f"{method.label}: options do not survive a JSON round trip: {record}")
    setup = MethodSetup.of_context(context, spps=(budget.spp,))
    for requirement in method.requirements():  # all but the kind: the contract runs every method on one context
        if not isinstance(requirement, SupportedKind):
            requirement.check(method, setup)
    warm_up(method, context)
    runs = []
    for _ in range(2):
        with count_samples() as counted:
            collect_recent_garbage()  # before the clock starts
            start = time.perf_counter()
            result = run_timed(method, context, budget)
            wall = time.perf_counter() - start
        seconds = check_result(method, result, context, budget)
        runs.append((result, seconds, wall, counted.path_samples))
    (first, seconds, wall, drawn), (second, *_) = runs
    assert first.path_samples == drawn, (
        f"{method.label}: reports {first.path_samples} path samples, the renderer drew {drawn}")
    timed = sum(seconds.values())
    assert timed <= wall * 1.02 + 1e-3, f"{method.label}: phases sum to {timed:.4f} s, more than the run's {wall:.4f} s"
    untimed = wall - timed
    assert untimed <= max(UNTIMED_TOLERANCE_SECONDS, UNTIMED_TOLERANCE_FRACTION * wall), (
        f"{method.label}: {untimed:.4f} s of a {wall:.4f} s run is in no phase")
    assert np.array_equal(first.image, second.image), f"{method.label}: the same seed gave another image"
    return {"result": first, "seconds": seconds, "wall_seconds": wall, "drawn": drawn}


__all__ = ["check_method", "check_result"]
