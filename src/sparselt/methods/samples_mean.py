"""Method ``samples-mean``: the ablation of the CoSaMP methods (same samples, no reconstruction)."""

from __future__ import annotations

from .base import Method, MethodResult
from .pixel_samples import sample_mean_image
from .registry import register


@register
class SamplesMean(Method):
    """Per-pixel mean of exactly the samples the CoSaMP methods receive (their ablation)."""

    name = "samples-mean"
    family = "ablation"
    kinds = ("dof", "indirect", "path", "path-indirect")
    description = "per-pixel mean of the CoSaMP methods' samples (the same budget without reconstruction)"

    def run(self, context, budget, timer):
        samples, image = sample_mean_image(context, budget, timer)
        return MethodResult(image=image, path_samples=samples.values.shape[0],
                            details={"nonfinite_samples": samples.nonfinite})
