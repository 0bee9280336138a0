"""Method ``pt``: plain path tracing, the baseline every method must beat at equal time."""

from __future__ import annotations

from .base import Method, MethodResult
from .registry import register


@register
class PathTracing(Method):
    """Mitsuba's ``path`` integrator at ``spp`` (kinds ``dof`` and ``path``).

    For kind ``indirect`` (one-bounce indirect light, which Mitsuba's ``path``
    cannot render alone) it is the same estimator as the signal kind's, with
    every PSS dimension uniform: path tracing of that integrand, averaged per
    pixel inside one Dr.Jit kernel (:meth:`MitsubaScene.render_estimator`).
    """

    name = "pt"
    baseline = True
    family = "path tracing"
    kinds = ("dof", "indirect", "path", "path-indirect")
    description = "path tracing: Mitsuba's path integrator (the kind's own estimator for 'indirect', 'path-indirect')"

    def run(self, context, budget, timer):
        if context.kind in ("indirect", "path-indirect"):
            with timer("sampling"):
                image, nonfinite = context.scene.render_estimator(context.layout, budget.spp, budget.seed)
            details = {"integrator": f"sparselt {context.kind} estimator, one kernel", "nonfinite_samples": nonfinite}
        else:
            image, seconds = context.scene.render_path(budget.spp, context.max_depth, budget.seed)
            timer.seconds["sampling"] += seconds
            details = {"integrator": "mitsuba path"}
        width, height = context.resolution
        return MethodResult(image=image, path_samples=width * height * budget.spp, details=details)
