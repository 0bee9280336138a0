r"""A method followed by a denoiser: ``METHOD+oidn`` (issue 37, 7).

Production renderers put a denoiser after their best estimator, not after
plain path tracing. ``METHOD+oidn`` is any registered method's image (an
axis-aligned filter's, a gradient-domain reconstruction's, a guided render's)
given to Intel Open Image Denoise with the albedo and normal of an ``aov``
pass, exactly as the ``oidn`` method denoises path tracing's image. Every
second counts: the method's own phases, the feature pass (``aov_spp``
samples per pixel, in ``sampling``) and the denoiser (in
``reconstruction``); the path samples are the method's.

Whether a pair beats both its parts is a measurement, not a given: the
denoiser is trained on path-traced noise, and a filtered or reconstructed
image carries correlated residuals of another shape. The composed row sits
beside its parts in the same comparison, so the equal-time verdicts answer
it.

The composed class is made on first use of its name (:func:`composed_class`)
and is not listed among the registered methods (``sparselt methods``); any
method that is not itself a denoiser composes, and its options are the
method's own plus ``aov_spp``: ``gradient-l1+oidn:demodulation=none``.

References
----------
Áfra, A. T. (2019-). Intel Open Image Denoise. Zimmer et al. (2015) and
Bako et al. (2017) on denoising the output of better estimators.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..filters import oidn_denoise
from .base import WARM_UP_SEED, MethodResult
from .filtered import AovOptions

#: The denoisers a method's image can be given to, by the name after ``+``.
DENOISERS = ("oidn",)

_COMPOSED = {}


def split_composition(name):
    """``(method, denoiser)`` of a composed name ``METHOD+DENOISER``, or ``None`` for a plain name."""
    if not isinstance(name, str) or "+" not in name:
        return None
    method, _, denoiser = name.rpartition("+")
    return method, denoiser


def composed_class(inner, denoiser):
    """The method class ``inner.name + '+' + denoiser``: ``inner``'s image, then the denoiser (module docstring).

    Parameters
    ----------
    inner : type
        A registered :class:`~sparselt.methods.base.Method` class whose
        family is not ``'denoiser'``.
    denoiser : str
        One of :data:`DENOISERS`.

    Raises
    ------
    ValueError
        An unknown denoiser, or a method that is itself a denoiser.
    """
    if denoiser not in DENOISERS:
        raise ValueError(f"method {inner.name}+{denoiser}: unknown denoiser {denoiser!r}; a method's image can be "
                         f"given to: {', '.join(DENOISERS)} (written METHOD+oidn)")
    if inner.family == "denoiser":
        raise ValueError(f"method {inner.name}+{denoiser}: {inner.name!r} is a denoiser itself; compose a method "
                         "that renders (e.g. aaf-indirect+oidn, gradient-l1+oidn)")
    key = (inner, denoiser)
    if key in _COMPOSED:
        return _COMPOSED[key]

    if issubclass(inner.Options, AovOptions):
        ComposedOptions = inner.Options  # it has its feature pass already
    elif issubclass(AovOptions, inner.Options):
        ComposedOptions = AovOptions  # no options of its own
    else:
        @dataclass(frozen=True)
        class ComposedOptions(inner.Options, AovOptions):
            """The method's options and the denoiser's feature pass."""

        ComposedOptions.__name__ = ComposedOptions.__qualname__ = f"{inner.Options.__name__}With{denoiser.title()}"

    class Composed(inner):
        name = f"{inner.name}+{denoiser}"
        composes = inner  # the method whose image the denoiser is given
        family = "denoiser"
        thesis_procedure = False
        baseline = False
        Options = ComposedOptions
        description = (f"{inner.name}'s image denoised by Intel Open Image Denoise (RT, hdr, albedo + normal from "
                       "an aov pass of aov_spp samples per pixel, timed)")

        def run(self, context, budget, timer):
            result = super().run(context, budget, timer)
            with timer("sampling"):
                buffers, _ = context.scene.render_aovs(self.options.aov_spp, budget.seed)
            with timer("reconstruction"):
                image = oidn_denoise(result.image, buffers["albedo"], buffers["normal"])
            details = dict(result.details, denoiser="pyoidn RT hdr, albedo + normal", aov_spp=self.options.aov_spp)
            return MethodResult(image=np.asarray(image, dtype=np.float32), path_samples=result.path_samples,
                                details=details)

        def warm_up(self, context):
            super().warm_up(context)
            buffers, _ = context.scene.render_aovs(1, WARM_UP_SEED)
            oidn_denoise(np.zeros_like(buffers["albedo"]), buffers["albedo"], buffers["normal"])

    Composed.__name__ = Composed.__qualname__ = f"{inner.__name__}With{denoiser.title()}"
    Composed.__module__ = __name__
    _COMPOSED[key] = Composed
    return Composed


__all__ = ["DENOISERS", "composed_class", "split_composition"]
