"""Image quality against a reference, the one set of metrics every experiment reports (thesis 8.1.1).

:func:`quality` is what ``compare`` and ``table61`` measure of each image:
SSIM (the project's HDR convention), relMSE with epsilon :data:`RELMSE_EPSILON`,
HDR-FLIP, the luminance and contrast ratios; :func:`caustic_mask` the pixels
where ``compare --caustic-mask`` also reports relMSE.
"""

from __future__ import annotations

import numpy as np

from ..analysis.metrics import (
    contrast_ratio,
    flip_error,
    image_ssim,
    luminance_ratio,
    relative_error_denominator,
    relative_mean_squared_error,
    trimmed_relative_mean_squared_error,
)
from ..images import luminance

#: relMSE's epsilon: (image - reference)^2 / (reference^2 + epsilon), averaged (every report states it).
RELMSE_EPSILON = 0.01


def caustic_mask(loaded, reference, *, spp, max_depth, seed=0, fraction=0.3):
    """Pixels lit by caustics: where caustic paths carry more than ``fraction`` of the radiance.

    Parameters
    ----------
    loaded : MitsubaScene
        The scene as loaded for the comparison (built-in or a scene file).
    reference : ndarray, shape (height, width, 3)
        The comparison's reference; only its black pixels enter (never in the
        mask). No method's image enters.
    spp : int
        Samples per pixel of the classification render.
    max_depth : int
        Longest path, Mitsuba's convention.
    seed : int, optional
        The classification render's seed.
    fraction : float, optional
        Least caustic share of a pixel's luminance, in ``[0, 1)``.

    Returns
    -------
    ndarray of bool, shape (height, width)

    Raises
    ------
    TypeError
        ``fraction`` is not a number.
    ValueError
        ``fraction`` outside ``[0, 1)``, or ``reference`` not of the film's
        shape; ``spp`` or ``max_depth`` below 1 (the render's own checks).

    Notes
    -----
    The renderer classifies the paths it traces
    (:meth:`~sparselt.rendering.mitsuba.MitsubaScene.render_path_classes`):
    a path is caustic when its light end is ``L S+ D`` (Heckbert's ``L S+ D
    (S|D)* E``; a vertex is specular when the BSDF component sampled there is
    a Dirac delta, glossy ones count as diffuse). A pixel is in the mask when
    the luminance its caustic paths carry exceeds ``fraction`` of its total
    luminance, both from the same ``spp`` paths (a ratio estimate, so noisy
    where either is), and neither that total nor the reference is black. The
    share is that of the full path image at ``max_depth`` whatever the
    comparison's kind: for kind ``indirect`` (whose reference leaves out
    paths of depth 2 or less) the mask still classifies the full image.
    """
    if isinstance(fraction, bool) or not isinstance(fraction, (int, float, np.integer, np.floating)):
        raise TypeError(f"fraction must be a number in [0, 1), got {fraction!r}")
    if not 0.0 <= float(fraction) < 1.0:
        raise ValueError(f"fraction must be in [0, 1) (the least caustic share of a pixel), got {fraction!r}")
    reference = np.asarray(reference)
    film = (loaded.height, loaded.width, 3)
    if reference.shape != film:
        raise ValueError(f"reference has shape {reference.shape}; the loaded scene's film needs {film}")
    images, _ = loaded.render_path_classes(spp, max_depth, seed)
    total = luminance(images["total"].astype(np.float64))
    caustic = luminance(images["caustic"].astype(np.float64))
    lit = (total > 0) & (luminance(reference) > 0)
    share = np.divide(caustic, total, out=np.zeros_like(total), where=lit)
    return lit & (share > float(fraction))


def quality(image, reference, mask=None, floor_map=None):
    """SSIM (the project's HDR convention), relMSE (epsilon 0.01), trimmed relMSE and its outlier share,
    HDR-FLIP, luminance and contrast ratios.

    Parameters
    ----------
    image, reference : ndarray, shape (height, width, 3)
    mask : ndarray of bool, shape (height, width), optional
        Also ``relmse_caustic``: the relMSE over the masked pixels only.
    floor_map : ndarray, shape (height, width), optional
        The reference's own contribution to each pixel's relMSE term
        (:func:`reference_floor_map`): also ``reference_relmse_floor`` (its
        mean) and ``reference_relmse_floor_trimmed`` (its mean over the pixels
        the trimmed relMSE keeps), which the equal-time protocol subtracts.

    Notes
    -----
    ``relmse_trimmed`` discards the top 0.1% of per-pixel errors (at least
    one pixel; the field's convention) and ``outlier_share`` is the share of
    relMSE those pixels held
    (:func:`~sparselt.analysis.metrics.trimmed_relative_mean_squared_error`).
    """
    trimmed, share, kept = trimmed_relative_mean_squared_error(image, reference, epsilon=RELMSE_EPSILON)
    record = {
        "ssim": image_ssim(image, reference),
        "flip": flip_error(image, reference),
        "relmse": relative_mean_squared_error(image, reference, epsilon=RELMSE_EPSILON),
        "relmse_trimmed": trimmed,
        "outlier_share": share,
        "luminance_ratio": luminance_ratio(image, reference),
        "contrast_ratio": contrast_ratio(image, reference),
    }
    if floor_map is not None:
        record["reference_relmse_floor"] = float(np.mean(floor_map))
        record["reference_relmse_floor_trimmed"] = float(np.mean(floor_map[kept]))
    if mask is not None:
        record["relmse_caustic"] = (relative_mean_squared_error(image[mask][None], reference[mask][None],
                                                                epsilon=RELMSE_EPSILON) if mask.any() else "")
    return record


def reference_floor_map(reference, variance):
    """The reference's own noise in each pixel's relMSE term: ``mean_c var_c / (mean_c reference_c^2 + eps)``.

    An image ``I`` measured against a noisy reference ``R = T + e`` (``e`` of
    variance ``v``, independent of ``I``) has ``E[(I - R)^2] = E[(I - T)^2] +
    v``: every relMSE term gains ``v`` over relMSE's denominator
    (:func:`~sparselt.analysis.metrics.relative_error_denominator`), whatever
    the image. ``variance`` is the per-pixel variance of the reference's mean
    from its passes; None (a one-pass reference) gives None.
    """
    if variance is None or not np.all(np.isfinite(variance)):
        return None
    variance = np.asarray(variance, dtype=np.float64)
    return np.mean(variance, axis=-1) / relative_error_denominator(reference, epsilon=RELMSE_EPSILON)


__all__ = ["RELMSE_EPSILON", "caustic_mask", "quality", "reference_floor_map"]
