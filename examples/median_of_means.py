"""A comparison method of one's own, as a plug-in: the median-of-means estimator of each pixel.

Run it beside the built-in methods, at equal time, without touching sparselt::

    PYTHONPATH=examples sparselt compare --plugin median_of_means \
        --scene cornell-box --kind dof --aperture 0.1 --shape 64,64,8,8 \
        --methods pt,median-of-means --spp 16,64 --option median-of-means.groups=8 --out out/mom

    PYTHONPATH=examples sparselt methods --plugin median_of_means median-of-means

Variants compare several settings in one run, each a row named as written:
``--methods pt,median-of-means,median-of-means:groups=2``.

What a plug-in needs is here: a :class:`~sparselt.methods.Method` subclass
decorated with :func:`~sparselt.methods.register`, with ``name``, ``kinds``
and ``run(context, budget, timer)``; options, if any, declared as a frozen
:class:`~sparselt.methods.MethodOptions` dataclass (the harness validates
them before anything runs; the instance carries them, typed, as
``self.options``); what it needs of the comparison, if anything, declared in
``requires`` (a thin lens, a least spp, ...: checked before anything
renders). Every second goes in one of the phases of the
:class:`~sparselt.methods.PhaseTimer` the harness passes as ``timer`` (its
phases are the result's seconds), every path sample is counted in
``path_samples``. The harness times the run itself, checks the result and
reports it in every table exactly like a built-in method's. A seed derived
from ``budget.seed`` by arithmetic (``budget.seed + 1``) is fine: the
renderer takes any non-negative seed.

The estimator: each pixel's ``spp`` path samples are split into ``groups``
groups of consecutive samples; the pixel is the median, per colour channel,
of the group means. It bounds the influence of a rare, very bright sample
(a firefly) on the pixel, at the price of a bias towards the typical value:
for the right-skewed radiance of caustics and small lights, a median of
means is darker than the mean. ``groups = 1`` is the plain sample mean (path
tracing of the same samples).

References
----------
Nemirovsky, A. and Yudin, D. (1983), Problem Complexity and Method
Efficiency in Optimization (the median of means). Lugosi, G. and Mendelson,
S. (2019), Mean estimation and regression under heavy-tailed distributions.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sparselt.methods import Method, MethodOptions, MethodResult, option, register
from sparselt.methods.pixel_samples import draw_pixel_samples


@dataclass(frozen=True)
class MedianOfMeansOptions(MethodOptions):
    groups: int = option(5, minimum=1, maximum=64,
                         help="groups of samples per pixel whose means the median takes (1: the plain mean); "
                              "at most spp groups are used")


def median_of_means(values, groups):
    """The median over ``groups`` of consecutive-sample group means, per pixel and channel.

    Parameters
    ----------
    values : ndarray, shape (pixels, spp, channels)
    groups : int
        At most ``spp`` are used; groups differ in size by at most one sample.

    Returns
    -------
    ndarray, shape (pixels, channels), float64
    """
    spp = values.shape[1]
    groups = max(1, min(int(groups), spp))
    edges = np.linspace(0, spp, groups + 1).round().astype(int)
    means = np.stack([values[:, start:stop].mean(axis=1, dtype=np.float64)
                      for start, stop in zip(edges[:-1], edges[1:])], axis=0)
    return np.median(means, axis=0)


@register
class MedianOfMeans(Method):
    """Per-pixel median of means of the path samples (a robust, biased estimator)."""

    name = "median-of-means"
    kinds = ("dof", "indirect", "path")
    family = "robust estimator"
    description = "per-pixel median of the means of groups of its path samples (example plug-in; biased)"
    Options = MedianOfMeansOptions

    def run(self, context, budget, timer):
        options = self.options
        with timer("sampling"):
            samples = draw_pixel_samples(context, budget)
        with timer("reconstruction"):
            width, height = context.resolution
            values = samples.values.reshape(height * width, samples.spp, 3)
            image = median_of_means(values, options.groups).reshape(height, width, 3).astype(np.float32)
        return MethodResult(image=image, path_samples=int(samples.values.shape[0]),
                            details={"groups": min(options.groups, samples.spp), "nonfinite_samples": samples.nonfinite})
