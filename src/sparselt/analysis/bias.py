"""Per-pixel bias test of a method's mean image against the reference (Welch's t-test).

A method is unbiased when the expectation of its image over seeds equals the
reference's expectation in every pixel. :func:`pixel_bias_test` tests that
hypothesis pixel by pixel with Welch's unequal-variance t-test between the
method's images over seeds and the reference, whose own noise (the variance of
its mean, from the spread of its passes) enters the test with its own degrees
of freedom, as Jung et al. (2020) propose for comparing two renderers. The
many pixels are tested together under the Benjamini-Hochberg false discovery
rate (Bonferroni optional), and the result is summarised as the fraction of
pixels found biased and the luminance ratio of the mean image with its
interval over seeds.

References
----------
Jung, A., Hanika, J. and Dachsbacher, C. (2020). Detecting bias in Monte Carlo
renderers using Welch's t-test. Journal of Computer Graphics Techniques (JCGT),
9(2), 1-25. http://jcgt.org/published/0009/02/01/

Welch, B. L. (1947). The generalization of "Student's" problem when several
different population variances are involved. Biometrika, 34(1-2), 28-35.

Benjamini, Y. and Hochberg, Y. (1995). Controlling the false discovery rate: a
practical and powerful approach to multiple testing. Journal of the Royal
Statistical Society B, 57(1), 289-300.
"""

from __future__ import annotations

import dataclasses
import math
import numbers

import numpy as np
from scipy import stats

from ..checks import check_integer, finite_float_array
from ..images import luminance

__all__ = ["BIAS_CORRECTIONS", "PixelBiasTest", "multiple_comparison_rejections", "pixel_bias_test"]

#: The multiple-comparison corrections :func:`pixel_bias_test` knows.
BIAS_CORRECTIONS = ("benjamini-hochberg", "bonferroni")
#: Confidence of the luminance ratio's interval over seeds.
INTERVAL_CONFIDENCE = 0.95


@dataclasses.dataclass(frozen=True, eq=False)
class PixelBiasTest:
    """The result of :func:`pixel_bias_test`.

    Attributes
    ----------
    p_values : ndarray, shape (height, width), float64
        Per pixel, the two-sided p-value of "the method's expectation equals
        the reference's", its channels combined (Bonferroni over channels).
    t_statistics : ndarray, shape (height, width) or (height, width, channels)
        Welch's t statistic per pixel and channel (``inf`` where both
        variances are 0 and the values differ, 0 where they are equal).
    degrees_of_freedom : ndarray, the shape of ``t_statistics``
        Welch-Satterthwaite degrees of freedom per pixel and channel.
    rejected : ndarray of bool, shape (height, width)
        The pixels found biased at ``level`` after ``correction``.
    biased_fraction : float
        ``rejected.mean()``: the fraction of pixels found biased.
    luminance_ratio : float
        The mean over seeds of each seed image's mean luminance over the
        reference's (:func:`sparselt.analysis.metrics.luminance_ratio`).
    luminance_ratio_interval : tuple of float
        Its 95% Student-t interval over seeds (the reference taken as exact).
    seeds : int
        The number of seed images.
    level : float
        The level the pixels were tested at.
    correction : str
        One of :data:`BIAS_CORRECTIONS`.
    """

    p_values: np.ndarray
    t_statistics: np.ndarray
    degrees_of_freedom: np.ndarray
    rejected: np.ndarray
    biased_fraction: float
    luminance_ratio: float
    luminance_ratio_interval: tuple
    seeds: int
    level: float
    correction: str


def _finite_array(value, name):
    hint = (" (a reference of one pass has no variance: pass reference_variance=None to take it as exact, or render "
            "the reference in more passes)" if name == "reference_variance" else "")
    return finite_float_array(value, name, hint=hint)


def _check_level(level):
    if isinstance(level, bool) or not isinstance(level, numbers.Real):
        raise TypeError(f"level must be a real number in (0, 1), got {level!r}")
    if not 0.0 < float(level) < 1.0:
        raise ValueError(f"level must be in (0, 1) (e.g. 0.01), got {level!r}")
    return float(level)


def multiple_comparison_rejections(p_values, *, level=0.01, correction="benjamini-hochberg"):
    """Which hypotheses are rejected at ``level`` among many, by ``correction``.

    Parameters
    ----------
    p_values : array_like
        One p-value per hypothesis, any shape, each in ``[0, 1]``.
    level : float, optional
        The false discovery rate (Benjamini-Hochberg) or the family-wise error
        rate (Bonferroni) controlled; in ``(0, 1)``.
    correction : {"benjamini-hochberg", "bonferroni"}, optional

    Returns
    -------
    ndarray of bool, the shape of ``p_values``

    Raises
    ------
    ValueError
        An unknown ``correction``, a ``level`` outside ``(0, 1)`` or a p-value
        outside ``[0, 1]``.

    Notes
    -----
    Of ``m`` p-values sorted ``p_(1) <= ... <= p_(m)``, Benjamini-Hochberg
    rejects the ``k`` smallest, ``k`` the largest index with
    ``p_(k) <= k level / m`` (none if there is none). Bonferroni rejects every
    ``p <= level / m``.

    References
    ----------
    Benjamini and Hochberg (1995), the step-up procedure of section 3.
    """
    level = _check_level(level)
    if correction not in BIAS_CORRECTIONS:
        raise ValueError(f"correction must be one of {', '.join(BIAS_CORRECTIONS)}; got {correction!r}")
    p_values = _finite_array(p_values, "p_values")
    if np.any((p_values < 0) | (p_values > 1)):
        raise ValueError(f"p_values must lie in [0, 1]; got values from {p_values.min()!r} to {p_values.max()!r}")
    count = p_values.size
    if count == 0:
        return np.zeros(p_values.shape, dtype=bool)
    if correction == "bonferroni":
        return p_values <= level / count
    ordered = np.sort(p_values, axis=None)
    passing = np.nonzero(ordered <= level * np.arange(1, count + 1) / count)[0]
    if passing.size == 0:
        return np.zeros(p_values.shape, dtype=bool)
    return p_values <= ordered[passing[-1]]


#: The relative standard deviation of float32 rounding in an image's pixel (about eight float32 units): every
#: difference smaller than this is taken as rounding, not bias (:func:`pixel_bias_test`).
ROUNDING_TOLERANCE = 1e-6


def pixel_bias_test(images, reference, reference_variance=None, *, reference_degrees_of_freedom=None, level=0.01,
                    correction="benjamini-hochberg"):
    """Welch's t-test per pixel of a method's images over seeds against the reference.

    Parameters
    ----------
    images : array_like, shape (seeds, height, width, channels) or (seeds, height, width)
        The method's image at each of ``seeds >= 2`` seeds (independent runs).
    reference : array_like, shape (height, width, channels) or (height, width)
        The reference image (the mean of its passes).
    reference_variance : array_like or None, optional
        The per-pixel variance of the reference's mean, the shape of
        ``reference`` (:func:`sparselt.rendering.baseline.cached_reference`'s
        record ``"variance"``). None takes the reference as exact (a
        one-sample t-test).
    reference_degrees_of_freedom : int, optional
        The degrees of freedom of ``reference_variance``: the number of the
        reference's passes minus 1. Required with ``reference_variance``.
    level : float, optional
        The false discovery rate (default 1%) or, with Bonferroni, the
        family-wise error rate.
    correction : {"benjamini-hochberg", "bonferroni"}, optional
        How the pixels' tests are combined (:func:`multiple_comparison_rejections`).

    Returns
    -------
    PixelBiasTest

    Raises
    ------
    ValueError
        Fewer than 2 seeds, shapes that do not match, NaN or infinite values,
        a negative variance, an unknown correction or a level outside (0, 1).
    TypeError
        A non-numeric array, or a non-integer ``reference_degrees_of_freedom``.

    Notes
    -----
    Per pixel and channel, with the method's ``n`` seed values ``x_i`` of mean
    ``m`` and sample variance ``s^2``, the reference ``r`` and the variance of
    its mean ``v`` with ``k`` degrees of freedom::

        t = (m - r) / sqrt(a + v),   a = s^2 / n,
        nu = (a + v)^2 / (a^2 / (n - 1) + v^2 / k)     (Welch-Satterthwaite)

    and the two-sided p-value ``2 P(T_nu > |t|)``. A reference of ``k + 1``
    passes is a second sample exactly as in Welch (1947) and Jung et al.
    (2020): with the passes as that sample this is
    ``scipy.stats.ttest_ind(..., equal_var=False)``. Without a variance
    (``v = 0``), ``nu = n - 1``: the one-sample t-test.

    A pixel whose two variances are both 0 (black in every seed and in every
    pass, or a constant background) carries no noise: it is unbiased
    (``p = 1``) if the method's value equals the reference's and biased
    (``p = 0``) otherwise. The seed images' luminance is not used for the test
    because the reference's variance is kept per channel without the
    covariances luminance's variance needs; instead every channel is tested
    and a pixel's p-value is ``min(1, channels * min_c p_c)``, the Bonferroni
    bound over its channels, valid whatever their correlation.

    The pixels are many (thousands) and a per-pixel 1% level would find about
    1% of an unbiased image's pixels biased. Benjamini-Hochberg at ``level``
    bounds the expected share of false findings among the pixels found
    biased; under the global null (an unbiased method) it rejects no pixel
    with probability at least ``1 - level`` for independent pixels (PT's
    pixels are). It keeps more power than Bonferroni, whose family-wise bound
    is stricter than this summary needs. A filter correlates neighbouring
    pixels; Benjamini-Hochberg stays valid under positive dependence
    (Benjamini and Yekutieli 2001) and is then a diagnostic, not an exact
    error rate.

    The luminance ratio is ``mean L(image_i) / mean L(reference)`` per seed
    (Rec. 709 luminance for RGB; the plain mean for other channel counts),
    averaged over seeds, with a Student-t interval at 95% over the seeds.

    References
    ----------
    Jung, Hanika and Dachsbacher (2020), sections 3-4 (Welch's t-test per
    pixel between two renderers); Welch (1947); Benjamini and Hochberg (1995).
    """
    images = _finite_array(images, "images")
    reference = _finite_array(reference, "reference")
    if images.ndim not in (3, 4):
        raise ValueError(f"images must have shape (seeds, height, width[, channels]); got shape {images.shape}")
    if images.shape[1:] != reference.shape:
        raise ValueError(f"images must be of shape (seeds, *reference.shape); got images.shape={images.shape} and "
                         f"reference.shape={reference.shape}")
    seeds = images.shape[0]
    if seeds < 2:
        raise ValueError(f"the bias test needs images of at least 2 seeds (a sample variance); got {seeds}")
    if images.shape[1] * images.shape[2] == 0:
        raise ValueError(f"images must not be empty; got shape {images.shape}")
    level = _check_level(level)
    if correction not in BIAS_CORRECTIONS:
        raise ValueError(f"correction must be one of {', '.join(BIAS_CORRECTIONS)}; got {correction!r}")
    if reference_variance is None:
        if reference_degrees_of_freedom is not None:
            raise ValueError("reference_degrees_of_freedom is given without reference_variance; pass both or neither")
        variance, reference_dof = np.zeros_like(reference), None
    else:
        variance = _finite_array(reference_variance, "reference_variance")
        if variance.shape != reference.shape:
            raise ValueError(f"reference_variance must have the reference's shape {reference.shape}; got "
                             f"{variance.shape}")
        if np.any(variance < 0):
            raise ValueError(f"reference_variance must be >= 0; got a minimum of {variance.min()!r}")
        if reference_degrees_of_freedom is None:
            raise ValueError("reference_variance needs reference_degrees_of_freedom (the reference's passes - 1)")
        reference_dof = check_integer("reference_degrees_of_freedom", reference_degrees_of_freedom, 1)

    mean = images.mean(axis=0)
    method_variance = images.var(axis=0, ddof=1) / seeds
    difference = mean - reference
    # Images are float32: a pixel every sample of which has one value (an emitter seen directly, a constant
    # background) has no variance in the method or the reference, and its two means still differ by rounding
    # (a float32 sum against a float64 mean of passes). Their rounding enters as a standard deviation of
    # ROUNDING_TOLERANCE of the pixel's value: without it, 28% of an unbiased PT's pixels on dof-sculptures were
    # "biased" by a difference of one float32 unit with a variance of exactly 0.
    rounding = (ROUNDING_TOLERANCE * np.maximum(np.abs(mean), np.abs(reference))) ** 2
    total = method_variance + variance + rounding
    noisy = total > 0
    with np.errstate(divide="ignore", invalid="ignore"):
        t_statistics = np.where(noisy, difference / np.sqrt(np.where(noisy, total, 1.0)),
                                np.where(difference == 0, 0.0, np.inf))
        if reference_dof is None:
            dof = np.full(mean.shape, float(seeds - 1))
        else:
            denominator = method_variance ** 2 / (seeds - 1) + variance ** 2 / reference_dof
            dof = np.where(noisy, total ** 2 / np.where(noisy, denominator, 1.0), float(seeds - 1 + reference_dof))
    channel_p = np.where(np.isinf(t_statistics), 0.0, 2.0 * stats.t.sf(np.abs(t_statistics), dof))
    if images.ndim == 4:
        channels = images.shape[3]
        p_values = np.minimum(1.0, channels * channel_p.min(axis=-1))
    else:
        p_values = channel_p
    rejected = multiple_comparison_rejections(p_values, level=level, correction=correction)

    ratio, interval = _luminance_ratio_interval(images, reference)
    return PixelBiasTest(p_values=p_values, t_statistics=t_statistics, degrees_of_freedom=dof, rejected=rejected,
                         biased_fraction=float(rejected.mean()), luminance_ratio=ratio,
                         luminance_ratio_interval=interval, seeds=seeds, level=level, correction=correction)


def _luminance_ratio_interval(images, reference):
    """The mean over seeds of the luminance ratio and its 95% Student-t interval (the reference exact)."""
    if images.ndim == 4 and images.shape[3] == 3:
        levels = luminance(images).mean(axis=(1, 2))
        base = float(luminance(reference).mean())
    else:
        levels = images.reshape(images.shape[0], -1).mean(axis=1)
        base = float(reference.mean())
    if base <= 0:
        raise ValueError("the reference is black (mean luminance <= 0): a luminance ratio is undefined")
    ratios = levels / base
    seeds = ratios.size
    centre = float(ratios.mean())
    half_width = float(stats.t.ppf(0.5 + INTERVAL_CONFIDENCE / 2, seeds - 1) * ratios.std(ddof=1) / math.sqrt(seeds))
    return centre, (centre - half_width, centre + half_width)
