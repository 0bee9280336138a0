r"""Gradient-domain reconstruction: screened Poisson by one DCT, and its L1 variant by ADMM (issue 23, first part).

An image ``I`` (height x width, any channels) is rebuilt from a noisy primal
estimate ``P`` and noisy forward-difference gradients ``G_x`` (height x
width-1) and ``G_y`` (height-1 x width), as in gradient-domain path tracing
(Kettunen et al. 2015, 4):

.. math:: \min_I\ \alpha^2 \lVert I - P\rVert^2 + \lVert D_x I - G_x\rVert^2 + \lVert D_y I - G_y\rVert^2

with ``(D_x I)(i, j) = I(i, j + 1) - I(i, j)``. Its normal equations are
``(alpha^2 + D_x^T D_x + D_y^T D_y) I = alpha^2 P + D_x^T G_x + D_y^T G_y``;
``D^T D`` along an axis of ``n`` pixels is the Neumann Laplacian, which the
orthonormal DCT-II diagonalises with eigenvalues ``4 sin^2(pi k / (2 n))``, so
the solve is exact: one forward and one inverse 2-D DCT (:func:`screened_poisson`).

The L1 variant (:func:`screened_poisson_l1`) minimises
``|| H I - b ||_1`` with ``H I = (alpha I, D_x I, D_y I)`` and ``b = (alpha P,
G_x, G_y)`` by ADMM (Boyd et al. 2011, 6.1; Kettunen et al. 2015 use the same
objective by iteratively reweighted least squares): each ``I`` step is the
same DCT solve with ``H^T H = alpha^2 + D^T D``, each ``z`` step a soft
threshold. It starts from the L2 solution (or the primal image), over-relaxed
(Boyd et al. 2011, 3.4.3, ``r = 1.6``), its ``I`` step in float32, with ADMM's
penalty in units of the data (the first version's plain ADMM from the primal
image in float64: :data:`PLAIN_ADMM`). Stop rule: an iteration moves the image by less
than ``tolerance`` (1e-3) times its norm, or ``max_iterations`` (50). Boyd et
al.'s residual rule (3.3.1) is not used: on rendered images the residuals
keep falling for hundreds of iterations while the image no longer changes
(measured in :mod:`sparselt.methods.gradient_domain`).

References
----------
Kettunen, M., Manzi, M., Aittala, M., Lehtinen, J., Durand, F., Zwicker, M.
(2015). Gradient-domain path tracing. ACM TOG 34(4). Boyd, S. et al. (2011).
Distributed optimization and statistical learning via ADMM. Bhat, P.,
Curless, B., Cohen, M., Zitnick, C. L. (2008). Fourier analysis of the 2D
screened Poisson equation for gradient domain problems. ECCV.
"""

from __future__ import annotations

import time

import numpy as np

from .. import kernels
from .result import RecoveryResult

DEFAULT_ALPHA = 0.2  # Kettunen et al. (2015)


def _check(primal, gradient_x, gradient_y, alpha):
    primal = np.asarray(primal, dtype=np.float64)
    if primal.ndim not in (2, 3) or min(primal.shape[:2]) < 2:
        raise ValueError(f"primal must be (height, width) or (height, width, channels) with both sides >= 2, got "
                         f"shape {primal.shape}")
    height, width = primal.shape[:2]
    gradient_x = np.asarray(gradient_x, dtype=np.float64)
    gradient_y = np.asarray(gradient_y, dtype=np.float64)
    expected_x = (height, width - 1) + primal.shape[2:]
    expected_y = (height - 1, width) + primal.shape[2:]
    if gradient_x.shape != expected_x:
        raise ValueError(f"gradient_x must have shape {expected_x} (forward differences along x), got {gradient_x.shape}")
    if gradient_y.shape != expected_y:
        raise ValueError(f"gradient_y must have shape {expected_y} (forward differences along y), got {gradient_y.shape}")
    if not (np.isfinite(alpha) and alpha > 0):
        raise ValueError(f"alpha must be a positive finite number, got {alpha!r}")
    for name, array in (("primal", primal), ("gradient_x", gradient_x), ("gradient_y", gradient_y)):
        if not np.all(np.isfinite(array)):
            raise ValueError(f"{name} holds NaN or infinite values")
    return primal, gradient_x, gradient_y


def forward_differences(image):
    """``(D_x I, D_y I)``: forward differences along x (axis 1) and y (axis 0)."""
    image = np.asarray(image, dtype=np.float64)
    return image[:, 1:] - image[:, :-1], image[1:] - image[:-1]


def difference_adjoint(gradient_x, gradient_y):
    """``D_x^T G_x + D_y^T G_y`` (zero flux across the border: Neumann)."""
    height, width = gradient_y.shape[0] + 1, gradient_x.shape[1] + 1
    result = np.zeros((height, width) + gradient_x.shape[2:])
    result[:, :-1] -= gradient_x
    result[:, 1:] += gradient_x
    result[:-1] -= gradient_y
    result[1:] += gradient_y
    return result


def _laplacian_eigenvalues(height, width, channels_shape):
    ky = 4.0 * np.sin(np.pi * np.arange(height) / (2.0 * height)) ** 2
    kx = 4.0 * np.sin(np.pi * np.arange(width) / (2.0 * width)) ** 2
    eigenvalues = ky[:, None] + kx[None, :]
    return eigenvalues.reshape(eigenvalues.shape + (1,) * len(channels_shape))


def _solve(right_hand_side, diagonal_shift, eigenvalues):
    """``(diagonal_shift + D^T D)^{-1} right_hand_side`` by the orthonormal DCT-II."""
    from scipy.fft import dctn, idctn

    spectrum = dctn(right_hand_side, type=2, norm="ortho", axes=(0, 1), workers=-1)
    spectrum /= diagonal_shift + eigenvalues
    return idctn(spectrum, type=2, norm="ortho", axes=(0, 1), workers=-1)


def screened_poisson(primal, gradient_x, gradient_y, *, alpha=DEFAULT_ALPHA):
    """The L2 reconstruction (module docstring): exact, two DCTs.

    Raises
    ------
    ValueError
        Shapes that do not fit together, non-finite input, alpha not positive.
    """
    primal, gradient_x, gradient_y = _check(primal, gradient_x, gradient_y, alpha)
    start = time.perf_counter()
    height, width = primal.shape[:2]
    right = alpha * alpha * primal + difference_adjoint(gradient_x, gradient_y)
    image = _solve(right, alpha * alpha, _laplacian_eigenvalues(height, width, primal.shape[2:]))
    return RecoveryResult(estimate=image, iterations=0, stop_reason="exact",
                          seconds={"solve": time.perf_counter() - start})


def screened_poisson_family(primal, gradient_x, gradient_y, alphas, *, precision="double"):
    """:func:`screened_poisson` for several ``alphas`` at once: two forward DCTs, one inverse DCT per alpha.

    The solution's spectrum is ``(alpha^2 P^ + (D^T G)^) / (alpha^2 + lambda)``
    with ``lambda`` the Neumann Laplacian's eigenvalues: the two forward
    transforms are shared. An alpha of ``inf`` is the primal image itself
    (the limit). Used by the held-out choice of alpha
    (:func:`held_out_alpha`).

    Parameters
    ----------
    precision : {'double', 'single'}
        ``'double'``: SciPy's float64 DCTs, images float64. ``'single'``:
        ducc0's float32 DCTs and spectra, images float32 (the held-out
        scores' images: about 4x cheaper, their errors far below the
        halves' noise).

    Returns
    -------
    list of ndarray
        One image per alpha, in order.
    """
    if precision not in ("single", "double"):
        raise ValueError(f"precision must be 'single' or 'double', got {precision!r}")
    finite = [alpha for alpha in alphas if np.isfinite(alpha)]
    primal, gradient_x, gradient_y = _check(primal, gradient_x, gradient_y, min(finite) if finite else 1.0)
    height, width = primal.shape[:2]
    eigenvalues = _laplacian_eigenvalues(height, width, primal.shape[2:])
    if precision == "single":
        return _single_precision_family(primal, difference_adjoint(gradient_x, gradient_y), eigenvalues, alphas)
    from scipy.fft import dctn, idctn

    primal_spectrum = dctn(primal, type=2, norm="ortho", axes=(0, 1), workers=-1)
    gradient_spectrum = dctn(difference_adjoint(gradient_x, gradient_y), type=2, norm="ortho", axes=(0, 1), workers=-1)
    images = []
    for alpha in alphas:
        if not np.isfinite(alpha):
            images.append(primal.copy())
            continue
        weight = alpha * alpha
        spectrum = (weight * primal_spectrum + gradient_spectrum) / (weight + eigenvalues)
        images.append(idctn(spectrum, type=2, norm="ortho", axes=(0, 1), workers=-1))
    return images


def _float32_dct(array, kind, out=None):
    """ducc0's DCT-II (``kind`` 2) or DCT-III (3) over the image axes, on every core: the float32 solves' transform
    (each the other's inverse up to the eigenvalues' division)."""
    import ducc0

    from ..fourier.fft import default_threads

    return ducc0.fft.dct(array, type=kind, axes=(0, 1), inorm=1, out=out, nthreads=default_threads())


def _single_precision_family(primal, adjoint, eigenvalues, alphas):
    """:func:`screened_poisson_family`'s images in float32 by ducc0's DCTs (as :func:`_single_precision_solver`)."""
    shape = primal.shape
    channels = int(np.prod(shape[2:], dtype=np.int64))

    def forward(array):
        return _float32_dct(np.ascontiguousarray(array, dtype=np.float32).reshape(shape[:2] + (channels,)), 2)

    primal_spectrum, gradient_spectrum = forward(primal), forward(adjoint)
    flat_eigenvalues = eigenvalues.reshape(shape[:2] + (-1,)).astype(np.float32)
    images = []
    for alpha in alphas:
        if not np.isfinite(alpha):
            images.append(primal.astype(np.float32))
            continue
        spectrum = kernels.screened_spectrum(primal_spectrum, gradient_spectrum, flat_eigenvalues, alpha * alpha,
                                             np.empty_like(primal_spectrum))
        images.append(_float32_dct(spectrum, 3, out=spectrum).reshape(shape))
    return images


#: The alphas :func:`held_out_alpha` chooses from: Kettunen et al.'s 0.2 in the middle of a factor-2 ladder, and the
#: primal image alone (``inf``: the gradients ignored).
HELD_OUT_ALPHAS = (0.05, 0.1, 0.2, 0.4, 0.8, 1.6, 3.2, float("inf"))


def held_out_alpha(halves, *, alphas=HELD_OUT_ALPHAS, epsilon=1e-2, return_images=False):
    """The alpha whose L2 reconstruction from one half of the samples best predicts the other half's primal image.

    Parameters
    ----------
    halves : sequence of two (primal, gradient_x, gradient_y)
        The estimates of two independent halves of the samples.
    alphas : sequence of float
        The candidates (``inf``: the primal image).
    epsilon : float
        relMSE's epsilon (0.01): the score's weights are
        ``1 / (mean over channels of m^2 + epsilon)``, ``m`` the mean of the
        two halves' reconstructions at Kettunen et al.'s alpha (0.2).
    return_images : bool
        Also return the halves' L2 images the scores were computed from.

    Returns
    -------
    alpha : float
        The candidate of least score.
    scores : dict
        ``{alpha: score}``, the score of each candidate.
    images : dict
        Only with ``return_images``: ``{alpha: (image_a, image_b)}``, each
        half's L2 image (float32, :func:`screened_poisson_family`'s single
        precision) at every candidate and at 0.2. The L2 solution is linear
        in the estimates, so the spp-weighted mean of a pair is the L2 image
        of all the samples at that alpha.

    Notes
    -----
    The primal image of half ``B`` is an unbiased estimate of the image,
    independent of half ``A``, so ``E |R_A - P_B|^2 = E |R_A - I|^2 + Var
    P_B``: the score, summed over both directions, is the reconstruction's
    expected squared error plus a term that does not depend on alpha (a
    held-out risk estimate, as in cross-validation; Stone 1974). No
    reference image is used. Where the gradients are poor (a shift that
    fails, caustics, fireflies) the score picks a large alpha or the primal
    image itself, which is path tracing with the offset paths as extra
    samples. Both halves' variances scale with ``1/spp`` alike, so the alpha
    chosen for half the samples is the alpha for all of them (the L2
    solution is linear in its inputs). :func:`held_out_choice` with one
    estimator.

    References
    ----------
    Stone, M. (1974). Cross-validatory choice and assessment of statistical
    predictions. J. R. Stat. Soc. B 36(2). Kettunen, M. et al. (2015).
    Gradient-domain path tracing. ACM TOG 34(4) (alpha = 0.2).
    """
    (_, alpha), scores, images = held_out_choice({None: halves}, alphas=alphas, epsilon=epsilon, return_images=True)
    scores = {alpha: score for (_, alpha), score in scores.items()}
    if return_images:
        return alpha, scores, {alpha: pair for (_, alpha), pair in images.items()}
    return alpha, scores


def held_out_choice(estimators, *, alphas=HELD_OUT_ALPHAS, epsilon=1e-2, significance=2.0, return_images=False):
    """The estimator and alpha whose L2 reconstruction from one half best predicts the other halves' primal images.

    Parameters
    ----------
    estimators : dict
        ``{label: halves}``, each ``halves`` two ``(primal, gradient_x,
        gradient_y)`` of independent halves of that estimator's samples; every
        estimator's samples independent of the others' (e.g. two shift maps
        with their own random numbers).
    alphas, epsilon
        As :func:`held_out_alpha`.
    significance : float
        The first estimator is the default: another replaces it only where
        its best score is lower by more than ``significance`` standard
        errors of the difference (estimated from the per-pixel score terms'
        sums over 8x8-pixel blocks). 0: the least score, however small the
        difference.
    return_images : bool
        Also return the halves' L2 images (as :func:`held_out_alpha`).

    Returns
    -------
    choice : tuple
        ``(label, alpha)``: each estimator's alpha of least score (ties: the
        smaller alpha), and of those the default unless another is
        significantly better (ties: the first label).
    scores : dict
        ``{(label, alpha): score}``.
    images : dict
        Only with ``return_images``: ``{(label, alpha): (image_a, image_b)}``
        for every candidate alpha (and 0.2).

    Notes
    -----
    Each reconstruction from half ``A`` of an estimator is judged against
    the same image for every estimator: the mean of all estimators' primal
    images of half ``B`` (and the other way round). That judge is unbiased
    and independent of every half-``A`` reconstruction, so ``E |R_A -
    J_B|^2 = E |R_A - I|^2 + E |J_B - I|^2`` with the second term shared by
    every candidate: score differences estimate differences of squared
    error, across estimators as across alphas (:func:`held_out_alpha`'s
    argument). Judging each estimator by its own other half would add its
    own primal's variance and favour the estimator with the quieter primal
    image, not the better reconstruction. With one estimator this is
    :func:`held_out_alpha`.

    The shared term is large on a pilot of a few samples per pixel, so
    estimators of nearly equal quality get nearly equal scores, and their
    order is then decided by noise: on dof-sculptures (256x256, pilot halves
    of 2 spp) the least score picked the reconnection shift in 2 of 3 seeds
    (score ratio 0.95-0.98), though at 16 spp its L2 images were 9-20% worse
    (trimmed relMSE); on cornell-box the ratio was 0.89-0.91, and the
    reconnection shift's images 2x better. Hence the significance rule.
    """
    labels = list(estimators)
    if not labels:
        raise ValueError("held_out_choice needs at least one estimator")
    candidates = tuple(float(alpha) for alpha in alphas)
    if DEFAULT_ALPHA not in candidates:
        candidates += (DEFAULT_ALPHA,)
    middle = candidates.index(DEFAULT_ALPHA)
    reconstructions = {}
    for label in labels:
        (primal_a, *gradients_a), (primal_b, *gradients_b) = estimators[label]
        reconstructions[label] = (screened_poisson_family(primal_a, *gradients_a, candidates, precision="single"),
                                  screened_poisson_family(primal_b, *gradients_b, candidates, precision="single"))
    count = float(len(labels))
    scale = sum(0.5 * (reconstructions[label][0][middle] + reconstructions[label][1][middle])
                for label in labels) / count
    weights = _score_weights(scale, epsilon)
    judge_b = sum(np.asarray(estimators[label][1][0], dtype=np.float64) for label in labels) / count
    judge_a = sum(np.asarray(estimators[label][0][0], dtype=np.float64) for label in labels) / count

    def pixel_terms(label, alpha):
        index = candidates.index(alpha)
        image_a, image_b = reconstructions[label][0][index], reconstructions[label][1][index]
        return kernels.held_out_terms(image_a, judge_b, image_b, judge_a, weights)

    scores = {(label, alpha): float(np.sum(pixel_terms(label, alpha)))
              for label in labels for alpha in candidates if alpha in alphas}
    best_of = {label: min((key for key in scores if key[0] == label), key=lambda key: (scores[key], key[1]))
               for label in labels}
    best = best_of[labels[0]]
    for label in labels[1:]:
        challenger = best_of[label]
        if scores[challenger] >= scores[best]:
            continue
        if significance and scores[best] - scores[challenger] <= significance * _block_standard_error(
                pixel_terms(*challenger) - pixel_terms(*best)):
            continue
        best = challenger
    if return_images:
        return best, scores, {(label, alpha): (reconstructions[label][0][index], reconstructions[label][1][index])
                              for label in labels for index, alpha in enumerate(candidates)}
    return best, scores


#: :func:`held_out_choice`'s blocks for the standard error of a score difference (pixels x pixels).
SCORE_BLOCK = 8


def _score_weights(image, epsilon):
    """relMSE's per-pixel weights ``1 / (mean over channels of image^2 + epsilon)`` of a held-out score."""
    return 1.0 / (np.mean(np.square(image), axis=-1, keepdims=True) + epsilon)


#: :func:`held_out_l1_check`'s ADMM iterations on each half (the full solve's default is at most 50).
L1_CHECK_ITERATIONS = 6


def held_out_l1_check(halves, alpha, *, iterations=L1_CHECK_ITERATIONS, epsilon=1e-2, significance=2.0,
                      l2_images=None, **l1_options):
    """Whether the L1 reconstruction at ``alpha`` predicts the held-out halves better than the L2 one, beyond noise.

    Parameters
    ----------
    halves : sequence of two (primal, gradient_x, gradient_y)
        The estimates of two independent halves of the samples (as
        :func:`held_out_alpha`).
    alpha : float
        The primal weight of both reconstructions (finite).
    iterations : int
        ADMM iterations of each half's L1 solve (from its L2 solution, as
        :func:`screened_poisson_l1`; most of the L1 solve's change comes in
        the first 5-20).
    epsilon : float
        relMSE's epsilon (0.01), as :func:`held_out_alpha`.
    significance : float
        The L1 image is chosen only where its score is lower by more than
        ``significance`` standard errors of the difference (from the
        per-pixel terms' sums over 8x8-pixel blocks); otherwise the L2 one,
        which costs one DCT solve instead of tens.
    l2_images : pair of ndarray, optional
        Each half's L2 image at ``alpha`` if computed already (``images[alpha]``
        of :func:`held_out_alpha` with ``return_images``); by default computed
        here, the same way (:func:`screened_poisson_family`, single precision).
    **l1_options
        Passed on to :func:`screened_poisson_l1` (tolerance, penalty, ...).

    Returns
    -------
    use_l1 : bool
        True where the L1 reconstruction is better beyond noise.
    record : dict
        ``difference`` (the L1 score minus the L2 score, summed over both
        directions), ``standard_error`` (of that difference), ``iterations``
        and ``significance``.

    Notes
    -----
    Each half is reconstructed both ways from its own samples and judged by
    the other half's primal image, with the same weights for both (from the
    mean of the halves' L2 images). The judge's own variance is the same
    for both reconstructions of a half, so it cancels in the *paired*
    difference, unlike the comparison of two estimators with their own
    samples (:func:`held_out_choice`), whose scores share only part of it.
    Studied on the standard suite's scenes at 256x256 before it was adopted
    (issue 37, sixth session; ``docs/experiments/suite-l1-check/study``, 3
    seeds, 5 iterations a half), in standard errors of the difference: L1
    better at -2.5 to -13 on cornell-box, courtyard, mirror-room,
    thin-geometry and glass-caustic (and dof-sculptures at 16 spp), where
    the full L1 image's trimmed relMSE was 0.26-0.98 of the L2 one's
    (``study-l1-iterations``; cornell-box from this study); L1
    worse at +0.6 to +2.2 (16 spp) and +7.7 to +8.5 (64 spp) on
    outdoor-texture and +5.4 to +6.7 on dof-sculptures at 64 spp, where it
    was 1.03-1.07; -2.2 to +1.4 on cornell-box at 64 spp, where it was
    1.00-1.02. The check costs about 0.4 of one full L1 solve (two halves'
    float32 L2 images, setups and iterations; ``benchmarks/poisson_solve.py``,
    256x256: 0.066 s); in the suite (``suite-fixed-costs``) it turned
    gradient-l1's one losing cell (outdoor-texture, 16 spp) from 0.72x with
    the unconditional L1 solve to 0.93x, within noise.
    """
    if not np.isfinite(alpha):
        raise ValueError(f"held_out_l1_check needs a finite alpha, got {alpha!r}")
    if int(iterations) < 1:
        raise ValueError(f"iterations must be at least 1, got {iterations!r}")
    (primal_a, *gradients_a), (primal_b, *gradients_b) = halves
    if l2_images is None:
        l2_images = (screened_poisson_family(primal_a, *gradients_a, (alpha,), precision="single")[0],
                     screened_poisson_family(primal_b, *gradients_b, (alpha,), precision="single")[0])
    elif len(l2_images) != 2 or any(np.shape(image) != np.shape(primal_a) for image in l2_images):
        raise ValueError(f"l2_images must be the two halves' images of shape {np.shape(primal_a)}")
    l1_images = tuple(screened_poisson_l1(primal, *gradients, alpha=alpha, max_iterations=iterations, start=l2,
                                          **l1_options).estimate
                      for (primal, *gradients), l2 in zip(halves, l2_images))
    weights = _score_weights(0.5 * (l2_images[0] + l2_images[1]), epsilon)
    judge_b, judge_a = np.asarray(primal_b, dtype=np.float64), np.asarray(primal_a, dtype=np.float64)
    terms = (kernels.held_out_terms(l1_images[0], judge_b, l1_images[1], judge_a, weights)
             - kernels.held_out_terms(l2_images[0], judge_b, l2_images[1], judge_a, weights))
    difference, standard_error = float(np.sum(terms)), _block_standard_error(terms)
    use_l1 = bool(difference < -significance * standard_error)
    return use_l1, {"difference": difference, "standard_error": standard_error, "iterations": int(iterations),
                    "significance": float(significance)}


def _block_standard_error(difference):
    """The standard error of ``difference.sum()`` from its sums over :data:`SCORE_BLOCK`-pixel squares, taken as
    independent (a reconstruction's errors are correlated over a few pixels, not over a block)."""
    height, width = difference.shape[:2]
    rows, columns = height // SCORE_BLOCK, width // SCORE_BLOCK
    if rows * columns < 2:
        return float("inf")
    blocks = difference[:rows * SCORE_BLOCK, :columns * SCORE_BLOCK].reshape(
        rows, SCORE_BLOCK, columns, SCORE_BLOCK, -1).sum(axis=(1, 3, 4)).ravel()
    # Scaled to the whole image (the pixels beyond the last whole block are few).
    return float(np.sqrt(blocks.size) * np.std(blocks, ddof=1) * (height * width) / (blocks.size * SCORE_BLOCK ** 2))


def _single_precision_solver(height, width, channels, diagonal_shift, eigenvalues):
    """``(diagonal_shift + D^T D)^{-1}`` by ducc0's orthonormal float32 DCT-II/III into reused buffers.

    Returns ``solve(right_hand_side, out)``: both ``(height, width, channels)``
    float32; ``out`` receives the solution (``right_hand_side`` is left as it was).
    """
    denominator = (diagonal_shift + eigenvalues).astype(np.float32)
    spectrum = np.empty((height, width, channels), dtype=np.float32)

    def solve(right_hand_side, out):
        _float32_dct(right_hand_side, 2, out=spectrum)
        np.divide(spectrum, denominator, out=spectrum)
        return _float32_dct(spectrum, 3, out=out)

    return solve


def l1_objective(image, primal, gradient_x, gradient_y, *, alpha=DEFAULT_ALPHA):
    """``|| H I - b ||_1 = alpha |I - P|_1 + |D_x I - G_x|_1 + |D_y I - G_y|_1``, what :func:`screened_poisson_l1` minimises.

    In float64 whatever the inputs' precision.
    """
    image = np.asarray(image, dtype=np.float64)
    difference_x, difference_y = forward_differences(image)
    return float(alpha * np.sum(np.abs(image - np.asarray(primal, dtype=np.float64)))
                 + np.sum(np.abs(difference_x - np.asarray(gradient_x, dtype=np.float64)))
                 + np.sum(np.abs(difference_y - np.asarray(gradient_y, dtype=np.float64))))


#: The plain ADMM of the first version (issue 23): primal start, no relaxation, float64 state and DCTs.
PLAIN_ADMM = {"start": "primal", "relaxation": 1.0, "precision": "double"}


def screened_poisson_l1(primal, gradient_x, gradient_y, *, alpha=DEFAULT_ALPHA, penalty=1.0, tolerance=1e-3,
                        max_iterations=50, start="l2", relaxation=1.6, precision="single"):
    """The L1 reconstruction ``min || H I - b ||_1`` by ADMM (module docstring).

    Parameters
    ----------
    penalty : float
        ADMM's ``rho`` in units of the data: ``rho = penalty / mean |b|``,
        so the iterations do not depend on the image's scale (ADMM on
        ``s b`` with ``rho / s`` takes the same steps, scaled).
    tolerance : float
        Stop when an iteration moves the image by less than ``tolerance``
        times its norm, ``||I_k - I_(k-1)|| < tolerance ||I_k||`` (the
        history of this ratio is the result's ``residual_history``).
    max_iterations : int
        Stop after this many iterations in any case.
    start : {'l2', 'primal'} or ndarray
        The first iterate: the L2 solution (the default: one more DCT solve,
        :func:`screened_poisson`, usually close to the L1 minimiser), the
        primal image (the first version's default), or an image of the
        primal's shape (e.g. the L2 solution computed already).
    relaxation : float
        ADMM's over-relaxation ``r`` in ``(0, 2)`` (Boyd et al. 2011,
        3.4.3): the ``z`` and dual steps see ``r H I + (1 - r) (z + b)``
        instead of ``H I``. 1 is plain ADMM; the default 1.6 took 15-20%
        fewer iterations to a given objective on rendered images (Notes).
    precision : {'single', 'double'}
        ``'single'`` (the default): the ``I`` step (its right-hand side, the
        DCTs by ducc0, the image) in float32; ``z``, ``u``, the element-wise
        arithmetic and the stop rule's sums stay float64. ``'double'``:
        everything in float64 (SciPy's DCT, the first version's arithmetic).
        The estimate is float64 either way.

    Returns
    -------
    RecoveryResult
        ``estimate`` the image (float64); ``residual_history`` the image's
        relative change per iteration; ``iterations`` the ``I`` steps run;
        ``stop_reason`` 'converged' (the change fell below ``tolerance``) or
        'max_iterations'; ``seconds`` of the whole solve.

    Raises
    ------
    ValueError
        As :func:`screened_poisson`, and for a penalty or tolerance that is
        not a positive finite number, ``max_iterations`` below 1, a
        relaxation outside ``(0, 2)``, an unknown ``start`` or ``precision``.

    Notes
    -----
    Scaled-form ADMM (Boyd et al. 2011, 3.1.1 and 6.1) on ``H I - z = b``,
    ``min |z|_1``, with over-relaxation (3.4.3)::

        I_(k+1) = (H^T H)^{-1} H^T (b + z_k - u_k)            (one DCT solve)
        h       = r H I_(k+1) + (1 - r) (z_k + b)
        z_(k+1) = soft(h - b + u_k, 1 / rho)
        u_(k+1) = u_k + h - b - z_(k+1)

    Every choice leaves the minimiser as it is (ADMM converges for any
    ``rho > 0``, ``r`` in ``(0, 2)`` and any start); each only changes how
    fast the iterates get there. Measured on 256x256 renders at 16 spp
    (``outdoor-texture`` indirect, ``cornell-box`` path; objective relative
    to a 3000-iteration plain run): plain ADMM from the primal image reached
    5.7e-3 in 50 iterations on the first (0.24 s) and stopped at 2.2e-2
    after 23 on the second (0.11 s); these defaults reached 4.2e-3 (0.125 s)
    and 1.6e-2 after 24 (0.07 s). Relaxation helps the first tens of
    iterations only (after 500 plain ADMM is ahead: 2.1e-4 against 2.9e-4).
    Residual balancing of ``rho`` (Boyd 3.4.1, ``mu = 10``, ``tau = 2``)
    drove ``rho`` down 16-64x and was 3-10x slower to a given objective;
    fast ADMM with restart (Goldstein et al. 2014) restarted every few
    iterations and gained nothing; neither is used. Measured again against
    references (issue 37, third session: trimmed relMSE, 256x256, 16 and 64
    spp, 6 suite scenes; ``docs/experiments/study-l1-iterations``),
    balancing every 10 iterations settled glass-caustic at 64 spp sooner
    (0.27 of the L2 image's relMSE after 50 iterations against 0.34 with a
    fixed ``rho``), cost 1-4% on the five others and ran every solve to the
    50-iteration cap (the stop rule stopped fixed-``rho`` solves after 20-44
    on four of them): the default stays a fixed ``rho``. The single-precision
    ``I`` step changed the objective reached by less than 1e-5 (relative)
    and made an iteration about 1.4x cheaper (its DCTs 4x).

    References
    ----------
    Boyd, S., Parikh, N., Chu, E., Peleato, B., Eckstein, J. (2011).
    Distributed optimization and statistical learning via the alternating
    direction method of multipliers. Foundations and Trends in Machine
    Learning 3(1). Kettunen, M. et al. (2015). Gradient-domain path tracing.
    ACM TOG 34(4), 4 (the L1 reconstruction). Goldstein, T., O'Donoghue, B.,
    Setzer, S., Baraniuk, R. (2014). Fast alternating direction optimization
    methods. SIAM J. Imaging Sciences 7(3).
    """
    primal, gradient_x, gradient_y = _check(primal, gradient_x, gradient_y, alpha)
    clock = time.perf_counter()
    if not (np.isfinite(penalty) and penalty > 0):
        raise ValueError(f"penalty must be a positive finite number, got {penalty!r}")
    if not (np.isfinite(tolerance) and tolerance > 0):
        raise ValueError(f"tolerance must be a positive finite number, got {tolerance!r}")
    if int(max_iterations) < 1:
        raise ValueError(f"max_iterations must be at least 1, got {max_iterations!r}")
    if isinstance(start, np.ndarray):
        if start.shape != primal.shape:
            raise ValueError(f"a start image must have the primal's shape {primal.shape}, got {start.shape}")
    elif start not in ("primal", "l2"):
        raise ValueError(f"start must be 'primal', 'l2' or an image, got {start!r}")
    if not (np.isfinite(relaxation) and 0 < relaxation < 2):
        raise ValueError(f"relaxation must be in (0, 2) (1: plain ADMM), got {relaxation!r}")
    if precision not in ("single", "double"):
        raise ValueError(f"precision must be 'single' or 'double', got {precision!r}")
    height, width = primal.shape[:2]
    eigenvalues = _laplacian_eigenvalues(height, width, primal.shape[2:])
    targets = (alpha * primal, gradient_x, gradient_y)
    size = sum(part.size for part in targets)
    penalty = penalty * size / (sum(float(np.sum(np.abs(part))) for part in targets) or 1.0)

    if isinstance(start, np.ndarray):
        image = np.asarray(start, dtype=np.float64)
    elif start == "primal":
        image = primal.copy()
    else:
        image = screened_poisson(primal, gradient_x, gradient_y, alpha=alpha).estimate
    # The iterations' element-wise passes run fused on every core (kernels.admm_*), on (height, width, channels)
    # views; with relaxation 1 in double precision they compute what the NumPy expressions of the steps compute
    # (tests/test_poisson.py).
    channels = int(np.prod(primal.shape[2:], dtype=np.int64))
    flat = [np.ascontiguousarray(part).reshape(part.shape[:2] + (channels,)) for part in targets]
    # The first z and u: z = soft(H I - b, 1 / rho), u = (H I - b) - z, the plain update from z = u = 0 (one pass;
    # the same bytes as those NumPy expressions).
    z = [np.zeros_like(part, dtype=np.float64) for part in flat]
    u = [np.zeros_like(part, dtype=np.float64) for part in flat]
    image = np.ascontiguousarray(image.reshape(height, width, channels))
    kernels.admm_update(image, image, flat, z, u, alpha, 1.0 / penalty)
    # Single precision: the DCT solve's input and output (right, image) in float32, z, u and b in float64.
    dtype = np.float32 if precision == "single" else np.float64
    right = np.empty((height, width, channels), dtype=dtype)
    image = image.astype(dtype)
    flat_eigenvalues = eigenvalues.reshape(height, width, -1)
    if precision == "single":
        solve = _single_precision_solver(height, width, channels, alpha * alpha, flat_eigenvalues)
        spare = np.empty_like(image)
    history = []
    stop = "max_iterations"
    iterations = 0
    for iterations in range(1, int(max_iterations) + 1):
        kernels.admm_right_hand_side(flat, z, u, alpha, right)
        previous = image
        if precision == "single":
            image = solve(right, spare)
            spare = previous
        else:
            image = _solve(right, alpha * alpha, flat_eigenvalues)
        if relaxation == 1.0 and precision == "double":
            change, norm = kernels.admm_update(image, previous, flat, z, u, alpha, 1.0 / penalty)
        else:
            change, norm = kernels.admm_relaxed_update(image, previous, flat, z, u, alpha, 1.0 / penalty, relaxation)
        history.append(float(np.sqrt(change) / (np.sqrt(norm) or 1.0)))
        if history[-1] < tolerance:
            stop = "converged"
            break
    return RecoveryResult(estimate=image.reshape(primal.shape).astype(np.float64), residual_history=tuple(history),
                          iterations=iterations, stop_reason=stop, seconds={"solve": time.perf_counter() - clock})
