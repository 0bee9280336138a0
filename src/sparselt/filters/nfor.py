r"""Nonlinearly weighted first-order regression (NFOR; Bitterli et al. 2016) on plain arrays.

The filter takes a Monte Carlo image split in two independent halves ``A``
and ``B`` (the samples of each pixel in two sets), the variance of each half's
pixel mean, and feature buffers (albedo, normal, depth, ...) split the same
way, and returns the denoised image. The steps and constants follow the paper
and its authors' implementation (Tungsten's ``denoiser``):

1. **Feature prefiltering** (paper 5.1). Each feature buffer ``g`` is
   NL-means filtered, each half with the weights of the other half
   (``g_A' = NLM(g_A; guide g_B)``, ``g_B' = NLM(g_B; guide g_A)``), window
   radius 5, patch radius 3, ``k = 0.5``. The variance of each half is
   estimated from the halves, ``Var(g_A) = Var(g_B) = (g_A - g_B)^2 / 2``.
   The regressions use the mean of the two prefiltered halves.
2. **First-order regression** (paper 4, 5.2). For every centre pixel ``c``
   and a window ``Omega_c`` (radius 9), the colour of half ``A`` is regressed
   on :math:`x_q = [1, f(q) - f(c)]`:

   .. math:: \beta_c = \arg\min_\beta \sum_{q \in \Omega_c} w_c(q)\,
             \lVert y_A(q) - x_q \beta \rVert^2 + \sum_{j \ge 1} \lambda_j \beta_j^2

   with NL-means weights ``w_c(q)`` (patch radius 3) computed on half ``B``
   (cross filtering; and the other way round for half ``B``) and a small
   ridge :math:`\lambda_j = \rho\,G_{jj} + 10^{-12} G_{00}` on the slopes
   only (:math:`G = X^T W X`; scale-free, so an affine function of the
   features is reproduced to within about :math:`\rho`).
3. **Collaborative filtering** (paper 4.2). Every centre's regression writes
   its reconstruction :math:`x_q \beta_c` to every pixel ``q`` of its window;
   each output pixel is the ``w_c(q)``-weighted mean of the reconstructions
   it received.
4. **Bandwidth selection** (paper 5.3). Steps 2-3 run for every NL-means
   bandwidth ``k`` (0.5 and 1.0). The mean squared error of the output
   :math:`F = (F_A + F_B) / 2` is estimated per pixel from the halves
   (independent noise):

   .. math:: \widehat{\mathrm{MSE}}(F) = \tfrac12 \big[(F_A - y_B)^2 - V_B
             + (F_B - y_A)^2 - V_A\big] - \tfrac14 (F_A - F_B)^2

   (the squared difference against the other noisy half, less that half's
   variance, is the half filter's squared bias plus its variance; the half
   difference estimates the variance, which averaging the halves halves).
   The error maps (mean over channels) are NL-means filtered (window radius
   9, patch radius 1, ``k = 1``, guided by the mean of the halves), each
   pixel selects the bandwidth of least filtered error, the binary selection
   maps are filtered with the same weights (a partition of unity, so seams
   blend), and the half outputs are :math:`F_h = \sum_k S_k F_h^k`.
5. **Second pass** (paper 5.4). The mean prefiltered features are NL-means
   filtered once more, guided by themselves with variance
   ``(g_A' - g_B')^2 / 4`` (window radius 2, patch radius 3, ``k = 0.5``),
   and the selected image :math:`(F_A + F_B) / 2` is regressed once more
   (steps 2-3, ``k = 1``), guided by itself with variance
   ``(F_A - F_B)^2 / 4``: the output.

NL-means distance (Rousselle et al. 2012, the form the paper uses), per pixel
pair ``(p, q)`` and guide channel, averaged over the channels and over the
patch offsets ``s`` for which both ``p + s`` and ``q + s`` are inside the
image:

.. math:: d^2(p, q) = \frac{(u_p - u_q)^2 - (V_p + \min(V_p, V_q))}
          {\varepsilon + k^2 (V_p + V_q)}, \qquad
          w = \exp(-\max(0, \overline{d^2}))

with ``eps = 1e-10``. Windows and patches are clipped at the border (no padded
values enter a sum).

Simplifications against the paper and its authors' code (deliberate):

- the feature variances come from the half difference alone (the authors
  use per-sample feature variances where the renderer gives them);
- one NL-means weight per pixel pair from the distance averaged over the
  guide's channels (the authors' colour weights take the least weight over
  the channels, and their feature prefilter filters each channel alone), so
  the error and selection maps are the channel mean, one per pixel;
- the regression of each colour half uses the mean of the two prefiltered
  feature halves (the authors pair half ``A`` with the features of half
  ``B``: their features come from the same samples as the colour, ours from
  independent passes);
- a small relative ridge of our choosing stabilises the solve; no distance
  clamp or minimum centre weight (the centre's weight is 1 here).

Implementation: the NL-means weights of every (centre, window offset) pair are
computed one offset at a time over the whole image (per-pixel terms, then a
separable patch sum) and stored as float32, ``(2 r + 1)^2`` values per pixel
(95 MB for 256x256 at radius 9); the regressions and the collaborative
gather run over rows in parallel, one window offset at a time across a row.
All loops are numba (``parallel=True``, ``cache=True``).

References
----------
Bitterli, B., Rousselle, F., Moon, B., Iglesias-Guitián, J. A., Adler, D.,
Mitchell, K., Jarosz, W. and Novák, J. (2016). Nonlinearly weighted
first-order regression for denoising Monte Carlo renderings. Computer
Graphics Forum 35(4), 107-117. Rousselle, F., Knaus, C. and Zwicker, M.
(2012). Adaptive rendering with non-local means filtering. ACM TOG 31(6).
The authors' implementation: Tungsten's ``src/denoiser`` (B. Bitterli,
github.com/tunabrain/tungsten), read for the constants, not copied.
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass

import numpy as np

#: Denominator floor of the NL-means distance (Rousselle et al. 2012).
DISTANCE_EPSILON = 1e-10
#: Slope ridge floor, times the window's total weight: keeps a constant feature column solvable (slope 0).
RIDGE_FLOOR = 1e-12
#: The second pass (paper 5.4; the authors' code): feature window radius and the colour weights' ``k``.
SECOND_FEATURE_RADIUS = 2
SECOND_PASS_BANDWIDTH = 1.0

_KERNELS = {}


def _kernels():
    """The numba kernels, compiled on first use (and cached on disk by numba)."""
    if _KERNELS:
        return _KERNELS
    import numba

    @numba.njit(parallel=True, cache=True)
    def nl_means_weights(guide, variance, radius, patch_radius, bandwidth, weights):
        """weights[o, y, x] = NL-means weight of centre (y, x) and neighbour (y, x) + offset o (0 outside)."""
        channels, height, width = guide.shape
        size = 2 * radius + 1
        squared_bandwidth = bandwidth * bandwidth
        term = np.empty((height, width))
        valid = np.empty((height, width))
        column = np.empty((height, width))
        column_count = np.empty((height, width))
        for index in range(size * size):
            dy = index // size - radius
            dx = index % size - radius
            for y in numba.prange(height):
                qy = y + dy
                for x in range(width):
                    qx = x + dx
                    if qy < 0 or qy >= height or qx < 0 or qx >= width:
                        term[y, x] = 0.0
                        valid[y, x] = 0.0
                        continue
                    total = 0.0
                    for channel in range(channels):
                        difference = guide[channel, y, x] - guide[channel, qy, qx]
                        here = variance[channel, y, x]
                        there = variance[channel, qy, qx]
                        total += ((difference * difference - (here + min(here, there)))
                                  / (DISTANCE_EPSILON + squared_bandwidth * (here + there)))
                    term[y, x] = total / channels
                    valid[y, x] = 1.0
            for y in numba.prange(height):
                for x in range(width):
                    column[y, x] = 0.0
                    column_count[y, x] = 0.0
                for sy in range(max(0, y - patch_radius), min(height, y + patch_radius + 1)):
                    for x in range(width):
                        column[y, x] += term[sy, x]
                        column_count[y, x] += valid[sy, x]
            for y in numba.prange(height):
                qy = y + dy
                for x in range(width):
                    qx = x + dx
                    if qy < 0 or qy >= height or qx < 0 or qx >= width:
                        weights[index, y, x] = 0.0
                        continue
                    total = 0.0
                    count = 0.0
                    for sx in range(max(0, x - patch_radius), min(width, x + patch_radius + 1)):
                        total += column[y, sx]
                        count += column_count[y, sx]
                    weights[index, y, x] = np.exp(-max(0.0, total / count))
        return weights

    @numba.njit(parallel=True, cache=True)
    def weighted_average(values, weights, radius, out):
        """out[:, y, x] = sum_o w[o, y, x] values[:, (y, x) + o] / sum_o w[o, y, x] (the NL-means filter)."""
        channels, height, width = values.shape
        size = 2 * radius + 1
        for y in numba.prange(height):
            total = np.zeros(width)
            accumulated = np.zeros((channels, width))
            for index in range(size * size):
                dy = index // size - radius
                dx = index % size - radius
                qy = y + dy
                if qy < 0 or qy >= height:
                    continue
                for x in range(max(0, -dx), min(width, width - dx)):
                    weight = np.float64(weights[index, y, x])
                    total[x] += weight
                    for channel in range(channels):
                        accumulated[channel, x] += weight * values[channel, qy, x + dx]
            for channel in range(channels):
                for x in range(width):
                    out[channel, y, x] = accumulated[channel, x] / total[x]
        return out

    @numba.njit(cache=True)
    def solve_ridge(gram, right_hand_side, ridge, coefficients):
        """Solve (G + diag(lambda)) beta = b by Cholesky; lambda_0 = 0, lambda_j = ridge G_jj + floor G_00."""
        parameters = gram.shape[0]
        outputs = right_hand_side.shape[1]
        matrix = gram.copy()
        for j in range(1, parameters):
            matrix[j, j] += ridge * gram[j, j] + RIDGE_FLOOR * gram[0, 0]
        lower = np.zeros((parameters, parameters))
        for i in range(parameters):
            for j in range(i + 1):
                total = matrix[i, j]
                for m in range(j):
                    total -= lower[i, m] * lower[j, m]
                if i == j:
                    lower[i, i] = np.sqrt(max(total, 1e-300))
                else:
                    lower[i, j] = total / lower[j, j]
        for output in range(outputs):
            forward = np.empty(parameters)
            for i in range(parameters):
                total = right_hand_side[i, output]
                for m in range(i):
                    total -= lower[i, m] * forward[m]
                forward[i] = total / lower[i, i]
            for i in range(parameters - 1, -1, -1):
                total = forward[i]
                for m in range(i + 1, parameters):
                    total -= lower[m, i] * coefficients[m, output]
                coefficients[i, output] = total / lower[i, i]
        return coefficients

    @numba.njit(parallel=True, cache=True)
    def regression_coefficients(target, features, weights, radius, ridge, coefficients):
        """coefficients[:, :, y, x]: the weighted first-order fit of ``target`` in the window of (y, x)."""
        outputs, height, width = target.shape
        feature_count = features.shape[0]
        parameters = feature_count + 1
        size = 2 * radius + 1
        for y in numba.prange(height):
            gram = np.zeros((parameters, parameters, width))
            right = np.zeros((parameters, outputs, width))
            design = np.empty((parameters, width))
            weighted = np.empty((parameters, width))
            for index in range(size * size):
                dy = index // size - radius
                dx = index % size - radius
                qy = y + dy
                if qy < 0 or qy >= height:
                    continue
                start = max(0, -dx)
                stop = min(width, width - dx)
                for x in range(start, stop):
                    weight = np.float64(weights[index, y, x])
                    design[0, x] = 1.0
                    weighted[0, x] = weight
                for j in range(feature_count):
                    for x in range(start, stop):
                        difference = features[j, qy, x + dx] - features[j, y, x]
                        design[j + 1, x] = difference
                        weighted[j + 1, x] = weighted[0, x] * difference
                for a in range(parameters):
                    for b in range(a, parameters):
                        for x in range(start, stop):
                            gram[a, b, x] += weighted[a, x] * design[b, x]
                    for output in range(outputs):
                        for x in range(start, stop):
                            right[a, output, x] += weighted[a, x] * target[output, qy, x + dx]
            matrix = np.empty((parameters, parameters))
            vector = np.empty((parameters, outputs))
            solution = np.empty((parameters, outputs))
            for x in range(width):
                for a in range(parameters):
                    for b in range(a, parameters):
                        matrix[a, b] = gram[a, b, x]
                        matrix[b, a] = gram[a, b, x]
                    for output in range(outputs):
                        vector[a, output] = right[a, output, x]
                solve_ridge(matrix, vector, ridge, solution)
                for a in range(parameters):
                    for output in range(outputs):
                        coefficients[a, output, y, x] = solution[a, output]
        return coefficients

    @numba.njit(parallel=True, cache=True)
    def collaborative_gather(features, weights, coefficients, radius, out):
        """out[:, y, x]: the w_c(q)-weighted mean of the reconstructions x_q beta_c of every centre c covering q."""
        feature_count, height, width = features.shape
        outputs = coefficients.shape[1]
        size = 2 * radius + 1
        for y in numba.prange(height):
            total = np.zeros(width)
            accumulated = np.zeros((outputs, width))
            reconstruction = np.empty((outputs, width))
            difference_row = np.empty(width)
            for index in range(size * size):
                dy = index // size - radius
                dx = index % size - radius
                cy = y - dy  # the centre whose window offset `index` lands on row y
                if cy < 0 or cy >= height:
                    continue
                start = max(0, dx)
                stop = min(width, width + dx)
                for output in range(outputs):
                    for x in range(start, stop):
                        reconstruction[output, x] = coefficients[0, output, cy, x - dx]
                for j in range(feature_count):
                    for x in range(start, stop):
                        difference_row[x] = features[j, y, x] - features[j, cy, x - dx]
                    for output in range(outputs):
                        for x in range(start, stop):
                            reconstruction[output, x] += coefficients[j + 1, output, cy, x - dx] * difference_row[x]
                for x in range(start, stop):
                    weight = np.float64(weights[index, cy, x - dx])
                    total[x] += weight
                    for output in range(outputs):
                        accumulated[output, x] += weight * reconstruction[output, x]
            for output in range(outputs):
                for x in range(width):
                    out[output, y, x] = accumulated[output, x] / total[x]
        return out

    _KERNELS.update(nl_means_weights=nl_means_weights, weighted_average=weighted_average, solve_ridge=solve_ridge,
                    regression_coefficients=regression_coefficients, collaborative_gather=collaborative_gather)
    return _KERNELS


@dataclass(frozen=True)
class NforResult:
    """What :func:`nfor_filter` returns.

    Attributes
    ----------
    image : ndarray, shape (height, width, channels), float64
        The denoised image, ``sum_k S_k (F_A^k + F_B^k) / 2``.
    halves : ndarray, shape (2, height, width, channels), float64
        The two half outputs ``F_A``, ``F_B`` under the selection.
    selection : ndarray, shape (bandwidths, height, width), float64
        The smoothed selection maps ``S_k`` (they sum to 1 per pixel).
    estimated_error : ndarray, shape (bandwidths, height, width), float64
        The smoothed per-pixel MSE estimate of each bandwidth's output.
    features : ndarray, shape (features, height, width), float64
        The prefiltered feature channels the regressions used.
    """

    image: np.ndarray
    halves: np.ndarray
    selection: np.ndarray
    estimated_error: np.ndarray
    features: np.ndarray


def _check_integer(name, value, minimum):
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def _check_positive(name, value, *, allow_zero=False):
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not np.isfinite(value) \
            or value < 0 or (value == 0 and not allow_zero):
        raise ValueError(f"{name} must be a finite number {'>=' if allow_zero else '>'} 0, got {value!r}")
    return float(value)


def _halves(array, name, shape=None):
    """A (2, height, width[, channels]) array as float64 (2, channels, height, width)."""
    array = np.asarray(array, dtype=np.float64)
    if array.ndim == 3:
        array = array[..., None]
    if array.ndim != 4 or array.shape[0] != 2:
        raise ValueError(f"{name} must have shape (2, height, width) or (2, height, width, channels) (the two "
                         f"halves first), got {array.shape}")
    if shape is not None and array.shape[1:3] != shape:
        raise ValueError(f"{name} has image shape {array.shape[1:3]}, the colour {shape}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name} has NaN or infinite values")
    return np.ascontiguousarray(np.moveaxis(array, -1, 1))


def nl_means_weights(guide, variance, *, radius, patch_radius, bandwidth):
    """NL-means weights of every (centre, window offset) pair (Rousselle et al. 2012's distance; module notes).

    Parameters
    ----------
    guide, variance : ndarray, shape (channels, height, width)
        The guide image and the variance of each of its values.
    radius, patch_radius : int
        Window and patch radius in pixels.
    bandwidth : float
        ``k``.

    Returns
    -------
    ndarray, shape ((2 radius + 1)**2, height, width), float32
        ``weights[o, y, x]``: offset ``o = (dy + radius) (2 radius + 1) + dx + radius``;
        0 where the neighbour is outside the image.
    """
    guide = np.ascontiguousarray(guide, dtype=np.float64)
    variance = np.ascontiguousarray(variance, dtype=np.float64)
    _, height, width = guide.shape
    weights = np.empty(((2 * radius + 1) ** 2, height, width), dtype=np.float32)
    return _kernels()["nl_means_weights"](guide, variance, int(radius), int(patch_radius), float(bandwidth), weights)


def regression_coefficients(target, features, weights, *, radius, ridge):
    """Per-pixel weighted first-order regression coefficients (step 2 of the module notes).

    Parameters
    ----------
    target : ndarray, shape (outputs, height, width)
    features : ndarray, shape (features, height, width)
    weights : ndarray, shape ((2 radius + 1)**2, height, width)
        As :func:`nl_means_weights` returns (any float dtype).
    radius : int
    ridge : float
        ``rho`` of the slope ridge.

    Returns
    -------
    ndarray, shape (features + 1, outputs, height, width), float64
        ``beta_c``: intercept first, then one slope per feature (of ``f(q) - f(c)``).
    """
    target = np.ascontiguousarray(target, dtype=np.float64)
    features = np.ascontiguousarray(features, dtype=np.float64)
    weights = np.ascontiguousarray(weights)
    outputs, height, width = target.shape
    coefficients = np.empty((features.shape[0] + 1, outputs, height, width))
    return _kernels()["regression_coefficients"](target, features, weights, int(radius), float(ridge), coefficients)


def collaborative_reconstruction(features, weights, coefficients, *, radius):
    """Every pixel: the weighted mean of the reconstructions of the windows that cover it (step 3)."""
    features = np.ascontiguousarray(features, dtype=np.float64)
    coefficients = np.ascontiguousarray(coefficients, dtype=np.float64)
    out = np.empty((coefficients.shape[1],) + features.shape[1:])
    return _kernels()["collaborative_gather"](features, np.ascontiguousarray(weights), coefficients, int(radius), out)


def box_filter(image, radius):
    """Mean over the ``(2 radius + 1)^2`` window clipped at the border, of a (height, width) or (n, height, width)."""
    image = np.asarray(image, dtype=np.float64)
    result = image
    for axis in (-2, -1):
        length = result.shape[axis]
        padded = np.concatenate([np.zeros_like(np.take(result, [0], axis=axis)),
                                 np.cumsum(result, axis=axis)], axis=axis)
        upper = np.minimum(np.arange(length) + radius + 1, length)
        lower = np.maximum(np.arange(length) - radius, 0)
        counts = (upper - lower).astype(np.float64)
        shape = [1] * result.ndim
        shape[axis] = length
        result = (np.take(padded, upper, axis=axis) - np.take(padded, lower, axis=axis)) / counts.reshape(shape)
    return result


def nl_means(values, weights, *, radius):
    """The NL-means filter: each pixel, the ``weights``-weighted mean of ``values`` (channels, height, width)."""
    values = np.ascontiguousarray(values, dtype=np.float64)
    out = np.empty_like(values)
    return _kernels()["weighted_average"](values, np.ascontiguousarray(weights), int(radius), out)


def prefilter_features(feature_halves, *, radius=5, patch_radius=3, bandwidth=0.5):
    """Cross NL-means prefiltering of each feature buffer's halves (paper 5.1), channels stacked.

    Half ``A`` is filtered with the weights of half ``B`` and the other way
    round; each half's variance is ``(g_A - g_B)^2 / 2``.

    Parameters
    ----------
    feature_halves : sequence of ndarray, each (2, channels, height, width) float64

    Returns
    -------
    ndarray, shape (2, total channels, height, width), float64
    """
    filtered = []
    for halves in feature_halves:
        variance = 0.5 * (halves[0] - halves[1]) ** 2
        filtered.append(np.stack([
            nl_means(halves[half], nl_means_weights(halves[1 - half], variance, radius=radius,
                                                    patch_radius=patch_radius, bandwidth=bandwidth), radius=radius)
            for half in range(2)]))
    return np.concatenate(filtered, axis=1)


def nfor_filter(colour_halves, colour_variances, feature_halves, *, radius=9, patch_radius=3, bandwidths=(0.5, 1.0),
                feature_radius=5, feature_patch_radius=3, feature_bandwidth=0.5, selection_patch_radius=1,
                second_pass=True, ridge=1e-7):
    r"""Denoise a two-half Monte Carlo image by NFOR (Bitterli et al. 2016; the module notes give the steps).

    Parameters
    ----------
    colour_halves : ndarray, shape (2, height, width, channels)
        The pixel means of the two halves of the samples, ``y_A`` and ``y_B``.
    colour_variances : ndarray, shape (2, height, width, channels)
        The variance of each half's pixel mean, ``V_A`` and ``V_B`` (non-negative).
    feature_halves : sequence of ndarray
        Each feature buffer's two halves, ``(2, height, width)`` or
        ``(2, height, width, channels)`` (from independent passes).
    radius : int, optional
        Regression window radius (default 9: 19x19 pixels); also the window
        of the error and selection map filter.
    patch_radius : int, optional
        NL-means patch radius of the colour weights (default 3).
    bandwidths : sequence of float, optional
        The NL-means ``k`` of each candidate filter (default 0.5 and 1.0).
    feature_radius, feature_patch_radius : int, optional
        Window and patch radius of the feature prefilter (default 5 and 3).
    feature_bandwidth : float, optional
        Its ``k`` (default 0.5, the authors' implementation).
    selection_patch_radius : int, optional
        Patch radius of the NL-means filter of the error and selection maps
        (default 1; ``k = 1``, guided by the mean of the halves).
    second_pass : bool, optional
        Run the second regression pass on the selected image (default True).
    ridge : float, optional
        Relative ridge ``rho`` on the slopes (default 1e-7).

    Returns
    -------
    NforResult

    Raises
    ------
    ValueError
        Shapes that do not match, NaN or infinite values, negative
        variances, a radius or bandwidth out of range; the message names it.
    TypeError
        ``second_pass`` not a bool.

    Notes
    -----
    Memory: the weights of one NL-means pass are ``(2 radius + 1)^2``
    float32 per pixel. Time grows as ``pixels x (2 radius + 1)^2 x
    (features + 1)^2`` per regression (four, five with the second pass).

    References
    ----------
    Bitterli et al. (2016), sections 4 (first-order regression, collaborative
    filtering), 5.1 (feature prefiltering), 5.3 (bandwidth selection), 5.4
    (second pass).
    """
    radius = _check_integer("radius", radius, 1)
    patch_radius = _check_integer("patch_radius", patch_radius, 0)
    feature_radius = _check_integer("feature_radius", feature_radius, 1)
    feature_patch_radius = _check_integer("feature_patch_radius", feature_patch_radius, 0)
    selection_patch_radius = _check_integer("selection_patch_radius", selection_patch_radius, 0)
    feature_bandwidth = _check_positive("feature_bandwidth", feature_bandwidth)
    ridge = _check_positive("ridge", ridge, allow_zero=True)
    if not isinstance(second_pass, (bool, np.bool_)):
        raise TypeError(f"second_pass must be True or False, got {second_pass!r}")
    if isinstance(bandwidths, (str, bytes)) or not hasattr(bandwidths, "__len__") or len(bandwidths) == 0:
        raise ValueError(f"bandwidths must be a non-empty sequence of numbers > 0, got {bandwidths!r}")
    bandwidths = tuple(_check_positive("bandwidths[...]", value) for value in bandwidths)
    colour = _halves(colour_halves, "colour_halves")
    height, width = colour.shape[2:]
    variances = _halves(colour_variances, "colour_variances", (height, width))
    if variances.shape != colour.shape:
        raise ValueError(f"colour_variances has {variances.shape[1]} channels, the colour {colour.shape[1]}")
    if np.any(variances < 0):
        raise ValueError("colour_variances has negative values; give the variance of each half's pixel mean")
    if isinstance(feature_halves, np.ndarray) or len(feature_halves) == 0:
        raise ValueError("feature_halves must be a non-empty sequence of arrays, one per feature buffer")
    buffers = [_halves(halves, f"feature_halves[{index}]", (height, width))
               for index, halves in enumerate(feature_halves)]
    prefiltered = prefilter_features(buffers, radius=feature_radius, patch_radius=feature_patch_radius,
                                     bandwidth=feature_bandwidth)
    features = 0.5 * (prefiltered[0] + prefiltered[1])
    outputs = []  # per bandwidth: (2, channels, height, width)
    errors = []
    for bandwidth in bandwidths:
        filtered = np.empty_like(colour)
        for half in range(2):
            weights = nl_means_weights(colour[1 - half], variances[1 - half], radius=radius,
                                       patch_radius=patch_radius, bandwidth=bandwidth)
            coefficients = regression_coefficients(colour[half], features, weights, radius=radius, ridge=ridge)
            filtered[half] = collaborative_reconstruction(features, weights, coefficients, radius=radius)
            del weights
        errors.append((0.5 * ((filtered[0] - colour[1]) ** 2 - variances[1] + (filtered[1] - colour[0]) ** 2
                              - variances[0]) - 0.25 * (filtered[0] - filtered[1]) ** 2).mean(axis=0))
        outputs.append(filtered)
    # The error and selection maps: NL-means filtered, guided by the mean of the halves and its variance.
    selection_weights = nl_means_weights(0.5 * (colour[0] + colour[1]), 0.25 * (variances[0] + variances[1]),
                                         radius=radius, patch_radius=selection_patch_radius, bandwidth=1.0)
    errors = nl_means(np.stack(errors), selection_weights, radius=radius)
    choice = np.argmin(errors, axis=0)
    selection = nl_means(np.stack([(choice == index).astype(np.float64) for index in range(len(bandwidths))]),
                         selection_weights, radius=radius)
    del selection_weights
    halves = sum(selection[index][None, None] * outputs[index] for index in range(len(bandwidths)))
    image = 0.5 * (halves[0] + halves[1])
    if second_pass:
        # Paper 5.4: the features once more, guided by themselves, then one regression of the selected image.
        final_features = []
        first = 0
        for buffer in buffers:
            channels = slice(first, first + buffer.shape[1])
            first += buffer.shape[1]
            combined = features[channels]
            variance = 0.25 * (prefiltered[0, channels] - prefiltered[1, channels]) ** 2
            final_features.append(nl_means(combined, nl_means_weights(combined, variance, radius=SECOND_FEATURE_RADIUS,
                                                                      patch_radius=feature_patch_radius,
                                                                      bandwidth=feature_bandwidth),
                                           radius=SECOND_FEATURE_RADIUS))
        features = np.concatenate(final_features)
        weights = nl_means_weights(image, 0.25 * (halves[0] - halves[1]) ** 2, radius=radius,
                                   patch_radius=patch_radius, bandwidth=SECOND_PASS_BANDWIDTH)
        coefficients = regression_coefficients(image, features, weights, radius=radius, ridge=ridge)
        image = collaborative_reconstruction(features, weights, coefficients, radius=radius)
    return NforResult(image=np.moveaxis(image, 0, -1), halves=np.moveaxis(halves, 1, -1), selection=selection,
                      estimated_error=errors, features=features)


def warm_up():
    """Compile every kernel on a tiny image (numba caches them on disk)."""
    generator = np.random.default_rng(0)
    colour = generator.random((2, 6, 6, 3))
    nfor_filter(colour, np.full_like(colour, 0.01), [generator.random((2, 6, 6, 3)), generator.random((2, 6, 6))],
                radius=2, patch_radius=1, feature_radius=1, feature_patch_radius=1)


__all__ = ["DISTANCE_EPSILON", "RIDGE_FLOOR", "SECOND_FEATURE_RADIUS", "SECOND_PASS_BANDWIDTH", "NforResult",
           "box_filter", "collaborative_reconstruction", "nfor_filter", "nl_means", "nl_means_weights",
           "prefilter_features", "regression_coefficients", "warm_up"]
