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
threshold. It starts from the primal image (or the L2 solution) with ADMM's
penalty in units of the data. Stop rule: an iteration moves the image by less
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


def _soft(value, threshold):
    return np.sign(value) * np.maximum(np.abs(value) - threshold, 0.0)


def screened_poisson_l1(primal, gradient_x, gradient_y, *, alpha=DEFAULT_ALPHA, penalty=1.0, tolerance=1e-3,
                        max_iterations=50, start="primal"):
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
    start : {'primal', 'l2'}
        The first iterate: the primal image (the default: a noisy but
        outlier-free image, from which a few iterations already take the
        gradients' information, measured on rendered images in
        :mod:`sparselt.methods.gradient_domain`) or the L2 solution (which
        spreads outlying gradients that the iterations must then undo).

    Returns
    -------
    RecoveryResult
        ``estimate`` the image; ``residual_history`` the image's relative
        change per iteration; ``seconds`` of the whole solve.
    """
    primal, gradient_x, gradient_y = _check(primal, gradient_x, gradient_y, alpha)
    clock = time.perf_counter()
    if not (np.isfinite(penalty) and penalty > 0):
        raise ValueError(f"penalty must be a positive finite number, got {penalty!r}")
    if not (np.isfinite(tolerance) and tolerance > 0):
        raise ValueError(f"tolerance must be a positive finite number, got {tolerance!r}")
    if int(max_iterations) < 1:
        raise ValueError(f"max_iterations must be at least 1, got {max_iterations!r}")
    if start not in ("primal", "l2"):
        raise ValueError(f"start must be 'primal' or 'l2', got {start!r}")
    height, width = primal.shape[:2]
    eigenvalues = _laplacian_eigenvalues(height, width, primal.shape[2:])
    targets = (alpha * primal, gradient_x, gradient_y)
    size = sum(part.size for part in targets)
    penalty = penalty * size / (sum(float(np.sum(np.abs(part))) for part in targets) or 1.0)

    def apply(image):
        differences = forward_differences(image)
        return (alpha * image,) + differences

    image = primal.copy() if start == "primal" else screened_poisson(primal, gradient_x, gradient_y, alpha=alpha).estimate
    residual = [h - b for h, b in zip(apply(image), targets)]
    z = [_soft(r, 1.0 / penalty) for r in residual]
    u = [r - zz for r, zz in zip(residual, z)]
    # The iterations' element-wise passes run fused on every core (kernels.admm_*), on (height, width, channels)
    # views; they compute what the NumPy expressions of the steps compute (tests/test_poisson.py).
    channels = int(np.prod(primal.shape[2:], dtype=np.int64))
    flat = [np.ascontiguousarray(part).reshape(part.shape[:2] + (channels,)) for part in targets]
    z = [part.reshape(part.shape[:2] + (channels,)).copy() for part in z]
    u = [part.reshape(part.shape[:2] + (channels,)).copy() for part in u]
    right = np.empty((height, width, channels))
    image = image.reshape(height, width, channels)
    flat_eigenvalues = eigenvalues.reshape(height, width, -1)
    history = []
    stop = "max_iterations"
    iterations = 0
    for iterations in range(1, int(max_iterations) + 1):
        kernels.admm_right_hand_side(flat, z, u, alpha, right)
        previous = image
        image = _solve(right, alpha * alpha, flat_eigenvalues)
        change, norm = kernels.admm_update(image, previous, flat, z, u, alpha, 1.0 / penalty)
        history.append(float(np.sqrt(change) / (np.sqrt(norm) or 1.0)))
        if history[-1] < tolerance:
            stop = "converged"
            break
    return RecoveryResult(estimate=image.reshape(primal.shape), residual_history=tuple(history),
                          iterations=iterations, stop_reason=stop, seconds={"solve": time.perf_counter() - clock})
