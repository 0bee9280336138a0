r"""The equal-time protocol: what "equal time" and "beats path tracing" mean in a comparison (thesis 8.1.1).

The thesis's question for its applications is whether a method gains image
quality *for the same computation time* (8.1.1). This module is the one place
that answers it, from a comparison's rows (one per method, spp and seed, each
with the median of its repeated timings):

1. **Path tracing's fits.** The baseline (``pt``) runs at a ladder of
   budgets. Its median time is fitted as :math:`t = a + b \cdot spp`
   (least squares over the ladder, relative residual reported), and its
   relMSE, per seed, as :math:`r = c / spp + f` (relative least squares,
   ``f >= 0``: the floor that the reference's own noise and any bias leave).
   Where that line leaves a relative residual above
   :data:`CURVED_FIT_LIMIT` on a ladder of at least :data:`CURVED_FIT_RUNGS`
   rungs, the metric does not fall at Monte Carlo's rate over the ladder
   (the trimmed relMSE under fireflies: trimming removes a share of the error
   that shrinks as spp grows) and the fit is :math:`r = c / spp^k + f`, one
   exponent ``k`` in :data:`EXPONENT_RANGE` for all seeds
   (:func:`fit_exponent`). PT's relMSE at time ``t`` is :math:`(c / spp(t)^k + f)
   \cdot g(spp(t))` with :math:`spp(t) = (t - a) / b`: ``g`` is the fit's local
   correction (:func:`rung_corrections`), at each rung the mean over seeds of
   measured over fitted, interpolated in log spp, so that a model that does
   not describe the ladder everywhere (courtyard's line read PT 9-11% low at
   64-256 spp in every seed) no longer biases every method's ratio there;
   the corrected mean curve is held non-increasing (:meth:`BaselineFit.mean_value`),
   and ``g``'s standard error widens the ratio's interval (step 3). Its SSIM
   at ``t`` is interpolated in log spp between its ladder's runs of the same
   seed. A time beyond the ladder has no value (nothing is extrapolated): the
   harness extends the ladder until it passes every method's time, within a
   cap.
2. **Metrics.** The headline is ``relmse_trimmed``: relMSE with the top
   0.1% of per-pixel errors discarded (at least one pixel), the field's
   convention (:data:`HEADLINE_METRIC`); untrimmed relMSE, SSIM and HDR-FLIP
   are judged beside it, and ``verdicts_disagree`` says when the trimmed,
   untrimmed and FLIP verdicts differ. ``outlier_share`` is the share of
   relMSE the discarded pixels held; a cell whose mean share is above 0.5 is
   ``outlier_dominated``. The untrimmed relMSE is the headline instead
   (``headline_metric`` says which) in folders measured before the trimmed
   metric, and where PT's trimmed values do not follow its ``c / spp +
   floor`` fit (relative residual above :data:`FIT_RESIDUAL_LIMIT`): on
   firefly scenes trimming discards the only pixels that found the light and
   PT's trimmed error rises with spp.
3. **Ratios and intervals.** Per (method, spp) and metric: the mean over
   seeds and its 95% Student-t interval; the ratio of the method's mean to
   PT's mean at the same (per-seed median) times, with a 95% interval by the
   delta method on the log ratio (t quantile, ``n - 1`` degrees of freedom;
   the seeds are paired; SSIM as PT's over the method's, HDR-FLIP as the
   method's over PT's, so that below 1 is better for all), widened by the
   timing's own uncertainty (:func:`timing_uncertainty`: PT read at the
   method's time divided and multiplied by ``1 + d``) and by PT's local
   correction's standard error (:func:`correction_uncertainty`, in
   quadrature on the log scale). Both relMSEs first
   lose the reference's own floor (the variance of the reference's mean from
   the spread of its passes, over relMSE's denominator; in the trimmed
   metric, over the pixels it keeps): the ratio is of debiased values.
4. **Reference-limited.** A cell is ``reference-limited``, with no ratio
   and no speed-up, when the reference's floor is at least half
   (:data:`REFERENCE_LIMITED_SHARE`) of the method's mean measured value or
   of PT's at the same time, i.e. when the debiased error is no larger than
   the reference's own noise, or when a seed's debiased value is not
   positive. ``reference_spp_needed`` is the reference that would resolve it,
   from the floor's 1/spp law
   (:func:`~sparselt.rendering.baseline.reference_spp_for_floor`).
5. **Verdict.** ``wins`` when the ratio's interval lies below 1, ``loses``
   when above, ``within noise`` when it covers 1, ``one seed`` when there is
   no interval. Verdicts are per budget; sentences never average over
   budgets.
6. **Equal-quality speed-up** (:func:`equal_quality_speedup`). PT's time to
   reach the method's debiased headline value, from its fits, over the
   method's time: a decreasing function of the ratio alone that is 1 at a
   ratio of 1, so its interval is the ratio's interval mapped through it
   and the speed-up's verdict is the ratio's. PT's fits are never read beyond
   its ladder: where PT would need more spp than its largest rung the
   speed-up is a lower bound (``speedup_bound`` ``'>'``, the value at that
   rung), never infinite.
7. **Bias.** Per (method, spp) over its seeds: the fraction of pixels that
   Welch's t-test against the reference finds biased, Benjamini-Hochberg at
   1% (:func:`bias_record`, :func:`sparselt.analysis.bias.pixel_bias_test`),
   and the luminance ratio's mean with its 95% Student-t interval.

References
----------
Thesis 8.1.1 (equal-time comparison), Figures 8.1 and 8.3. Bienaymé/delta
method for ratio intervals: Casella and Berger (2002), 5.5.4. Bias: Jung,
Hanika and Dachsbacher (2020), JCGT 9(2).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..rendering.baseline import reference_spp_for_floor
from ..report.comparison_rows import group_mean, method_spp_groups

#: Two-sided 95% intervals.
CONFIDENCE = 0.95
#: A cell whose slowest repeat took more than this many times its fastest is flagged noisy.
NOISY_TIMING_RATIO = 1.5
VERDICTS = ("wins", "loses", "within noise", "one seed", "no PT value", "reference-limited")


def t_quantile(degrees):
    """The two-sided 95% Student-t quantile (scipy's, exact)."""
    from scipy.stats import t

    return float(t.ppf(0.5 + CONFIDENCE / 2, degrees))


def mean_interval(values):
    """``(mean, low, high)``: the mean of ``values`` and its 95% Student-t interval (``nan`` bounds for one value)."""
    values = np.asarray(values, dtype=np.float64)
    mean = float(values.mean())
    if values.size < 2:
        return mean, math.nan, math.nan
    half = t_quantile(values.size - 1) * float(values.std(ddof=1)) / math.sqrt(values.size)
    return mean, mean - half, mean + half


def ratio_interval(numerator, denominator):
    """Ratio of means of paired samples with its 95% delta-method interval on the log scale.

    ``var(log(mean x / mean y)) ~ var(x)/(n mean x^2) + var(y)/(n mean y^2)
    - 2 cov(x, y)/(n mean x mean y)``; the interval is
    ``exp(log ratio +- t_{n-1} sd)``. ``nan`` bounds for one pair.
    """
    x, y = np.asarray(numerator, np.float64), np.asarray(denominator, np.float64)
    ratio = float(x.mean() / y.mean())
    if x.size < 2 or not ratio > 0:
        return ratio, math.nan, math.nan
    covariance = np.cov(x, y, ddof=1)
    variance = (covariance[0, 0] / x.mean() ** 2 + covariance[1, 1] / y.mean() ** 2
                - 2 * covariance[0, 1] / (x.mean() * y.mean())) / x.size
    half = t_quantile(x.size - 1) * math.sqrt(max(variance, 0.0))
    return ratio, ratio * math.exp(-half), ratio * math.exp(half)


def verdict(low, high):
    """``wins`` / ``loses`` / ``within noise`` / ``one seed`` from a ratio's interval (below 1 is better)."""
    if not (math.isfinite(low) and math.isfinite(high)):
        return "one seed"
    if high < 1:
        return "wins"
    if low > 1:
        return "loses"
    return "within noise"


#: The headline metric of a comparison's verdicts and speed-ups: relMSE with the top 0.1% of per-pixel errors
#: discarded (the field's convention); folders measured before it existed fall back to ``relmse``.
HEADLINE_METRIC = "relmse_trimmed"
#: The relMSE metrics a comparison judges, each with the row column holding the reference's floor in it.
RELMSE_METRICS = {"relmse_trimmed": "reference_relmse_floor_trimmed", "relmse": "reference_relmse_floor"}
#: A cell is reference-limited when the reference's floor is at least this share of its (or PT's) measured mean:
#: its debiased error is then no larger than the reference's own noise.
REFERENCE_LIMITED_SHARE = 0.5
#: Rows whose top 0.1% of pixels hold more than this share of their relMSE are marked (a few pixels decide it).
OUTLIER_DOMINATED_SHARE = 0.5


#: PT's headline fit must describe its ladder: above this relative RMS residual (median over seeds) the trimmed
#: metric does not fall as ``c / spp^k + floor`` and the untrimmed relMSE decides instead (:func:`headline_metric`).
FIT_RESIDUAL_LIMIT = 0.5
#: Above this relative RMS residual (median over seeds) of ``c / spp + floor`` on a ladder of at least
#: :data:`CURVED_FIT_RUNGS` rungs, the exponent of spp is fitted too (:func:`fit_exponent`). Measured on the
#: committed comparisons: the 1/spp line leaves at most 0.15 except on firefly and caustic scenes, where the trimmed
#: relMSE's residuals run in one arc (dusk-indirect: +31%, 0, -50%, 0, +37% from 8 to 4096 spp; 0.30 in all), and
#: PT's fitted error halfway up the ladder was 0.6 of its measured one.
CURVED_FIT_LIMIT = 0.2
CURVED_FIT_RUNGS = 4
#: The exponents :func:`fit_exponent` chooses from: Monte Carlo's 1 down to 0.5, in steps of 0.01.
EXPONENT_RANGE = (0.5, 1.0)
#: A curve replaces the line only where it leaves at most this share of the line's residual: on glass-caustic the
#: best power (0.69) left 0.18 of the line's 0.26, trading the line's misfit at 512 spp (-44%) for one at 128 (+31%
#: against +1%); on dusk-indirect and atelier-indirect it left 0.06 and 0.10 of 0.30 and 0.27.
CURVE_GAIN = 0.5
#: :meth:`BaselineFit.spp_reaching`'s log-spp grid over the ladder and bisection steps within a grid interval.
REACHING_GRID = 512
REACHING_BISECTIONS = 60


def headline_metric(rows, fit=None):
    """The metric of a comparison's verdicts and speed-ups: :data:`HEADLINE_METRIC`, or ``'relmse'``.

    ``'relmse'`` when a row lacks the trimmed metric (a folder measured before
    it), or when PT's trimmed values do not follow its model: ``fit``'s
    relative residual for it above :data:`FIT_RESIDUAL_LIMIT`. Where every
    pixel that found a rare light is a firefly (sunlight through glass at a
    few spp), trimming discards exactly those pixels, PT's trimmed error then
    *rises* with spp until the light is found everywhere (measured on
    ``sunlit-room``: 0.09 at 8-16 spp, 4.6 at 64, 2.2 at 256), and no
    equal-time reading of it is meaningful.
    """
    if not rows or not all(row.get(HEADLINE_METRIC) not in ("", None) for row in rows):
        return "relmse"
    if fit is not None and fit.residuals.get(HEADLINE_METRIC, 0.0) > FIT_RESIDUAL_LIMIT:
        return "relmse"
    return HEADLINE_METRIC


def judged_metrics(rows):
    """The relMSE metrics of :data:`RELMSE_METRICS` that every row has, headline first."""
    return [metric for metric in RELMSE_METRICS if rows and all(row.get(metric) not in ("", None) for row in rows)]


def row_floor(row, metric):
    """The reference's floor in ``metric`` for ``row`` (0 when the reference had no variance)."""
    value = row.get(RELMSE_METRICS[metric], "")
    if value in ("", None) and metric != "relmse":
        value = row.get("reference_relmse_floor", "")
    return float(value) if value not in ("", None) and math.isfinite(float(value)) else 0.0


@dataclass(frozen=True)
class BaselineFit:
    """Path tracing's time and relMSE against spp, fitted on its ladder (see the module docstring).

    Attributes
    ----------
    intercept, slope : float
        ``t = intercept + slope * spp`` (seconds).
    time_residual : float
        Root-mean-square relative residual of the time fit.
    fits : dict
        ``{metric: {seed: (c, floor)}}`` for each relMSE metric of
        :data:`RELMSE_METRICS` the rows have: ``value = c / spp + floor``.
    ssim, flip : dict
        ``{seed: [(spp, value), ...]}`` sorted by spp (``flip`` empty for rows without FLIP).
    spp_range : tuple of int
        The ladder's smallest and largest spp.
    reached_seconds, lowest_seconds : float
        The times the ladder covers: from its smallest rung's fitted or
        measured time, whichever is smaller, to its largest rung's, whichever
        is larger. Between a rung's fitted and measured times PT's values are
        those of the rung itself (its spp is clamped to the ladder): PT then
        had at least the method's time, which can only favour PT.
    floors : dict
        ``{metric: floor}``: the reference's floor in PT's rows (their median).
    residuals : dict
        ``{metric: residual}``: the median over seeds of the root-mean-square
        relative residual of PT's ``c / spp^k + floor`` fit on its ladder.
    exponents : dict
        ``{metric: k}`` for the metrics whose fit has an exponent other than
        1 (:func:`fit_exponent`); the others fall as ``c / spp + floor``.
    corrections : dict
        ``{metric: (spps, means, standard_errors)}``, the fit's local
        correction (:func:`rung_corrections`): at each rung the mean over
        seeds of ``measured / fitted`` and its standard error. Empty: no
        correction (a fit built by hand).
    """

    intercept: float
    slope: float
    time_residual: float
    fits: dict
    ssim: dict
    spp_range: tuple
    reached_seconds: float
    lowest_seconds: float
    flip: dict = field(default_factory=dict)
    floors: dict = field(default_factory=dict)
    residuals: dict = field(default_factory=dict)
    exponents: dict = field(default_factory=dict)
    corrections: dict = field(default_factory=dict)

    def exponent(self, metric):
        """The exponent ``k`` of spp in ``metric``'s fit (1: Monte Carlo's rate)."""
        return self.exponents.get(metric, 1.0)

    def correction(self, metric, spp):
        """``(factor, standard_error)`` of ``metric``'s local correction at ``spp`` (a number or an array): the
        rungs' mean ``measured / fitted`` and its standard error, interpolated in log spp between the rungs
        (their end values beyond them); ``(1, 0)`` without a correction."""
        entry = self.corrections.get(metric)
        if entry is None:
            return (np.ones_like(spp, dtype=np.float64), np.zeros_like(spp, dtype=np.float64)) if np.ndim(spp) else (
                1.0, 0.0)
        spps, means, errors = entry
        position = np.log(spp)
        return np.interp(position, np.log(spps), means), np.interp(position, np.log(spps), errors)

    def corrected_value(self, metric, spp):
        """The seeds' mean fit times its local correction at ``spp`` (a number or an array):
        ``(c / spp^k + floor) * correction``, before :meth:`mean_value` makes it non-increasing."""
        c, floor = self.mean_fit(metric)
        return fitted_value(c, floor, spp, self.exponent(metric)) * self.correction(metric, spp)[0]

    def mean_value(self, metric, spp):
        """PT's ``metric`` at ``spp`` (a number or an array within the ladder): the running minimum over the
        ladder's spp up to ``spp`` of :meth:`corrected_value`. PT given more time is read as never worse: where
        the corrected curve rises between rungs (rung noise near a floor), it is held at its lowest value
        before, so PT's quality and the equal-quality speed-up (:meth:`spp_reaching`) read one non-increasing
        curve."""
        return self._held(metric, spp, self._running_minimum(metric))

    def _running_minimum(self, metric):
        """:meth:`corrected_value` on a :data:`REACHING_GRID`-point log grid over the ladder, and its running
        minimum: ``(grid, running)``, what :meth:`_held` reads."""
        grid = np.geomspace(*self.spp_range, REACHING_GRID)
        return grid, np.minimum.accumulate(self.corrected_value(metric, grid))

    def _held(self, metric, spp, running_minimum):
        """:meth:`mean_value` at ``spp`` given :meth:`_running_minimum`'s ``(grid, running)``."""
        grid, running = running_minimum
        spp = np.asarray(spp, dtype=np.float64)
        before = np.clip(np.searchsorted(grid, spp, side="right") - 1, 0, grid.size - 1)
        value = np.minimum(self.corrected_value(metric, spp), running[before])
        return float(value) if value.ndim == 0 else value

    def spp_reaching(self, metric, targets):
        """The least spp of PT's ladder at which :meth:`mean_value` falls to each of ``targets`` (an array).

        Returns ``(spp, bound)``: arrays of ``targets``' shape; ``bound`` is
        ``'>'`` where the ladder's largest rung does not reach the target
        (``spp`` is then that rung), ``'<'`` where its smallest already does
        (``spp`` that rung), ``''`` otherwise: located on a
        :data:`REACHING_GRID`-point log grid, refined by bisection to float
        precision (:meth:`mean_value` is non-increasing).
        """
        targets = np.asarray(targets, dtype=np.float64)
        lowest, highest = self.spp_range
        running_minimum = self._running_minimum(metric)  # once for the grid and every bisection step
        grid = running_minimum[0]
        values = self._held(metric, grid, running_minimum)
        index = np.searchsorted(-values, -targets, side="left")  # the first grid point at or below the target
        below, beyond = index == 0, index >= grid.size
        left = np.log(grid[np.clip(index - 1, 0, grid.size - 1)])
        right = np.log(grid[np.clip(index, 0, grid.size - 1)])
        for _ in range(REACHING_BISECTIONS):  # mean_value(exp(left)) > target >= mean_value(exp(right))
            middle = 0.5 * (left + right)
            reached = self._held(metric, np.exp(middle), running_minimum) <= targets
            right, left = np.where(reached, middle, right), np.where(reached, left, middle)
        spp = np.where(below, float(lowest), np.where(beyond, float(highest), np.exp(right)))
        bound = np.where(below, "<", np.where(beyond, ">", ""))
        return spp, bound

    @property
    def relmse(self):
        """``{seed: (c, floor)}`` of the untrimmed relMSE."""
        return self.fits.get("relmse", {})

    def spp_at(self, seconds):
        """PT's spp at ``seconds`` from the time fit, clamped to the ladder's range."""
        spp = (seconds - self.intercept) / self.slope
        return min(max(spp, self.spp_range[0]), self.spp_range[1])

    def seconds_at(self, spp):
        return self.intercept + self.slope * spp

    def covers(self, seconds):
        """Whether ``seconds`` lies within the ladder's times (no extrapolation at either end)."""
        return self.lowest_seconds * (1 - 1e-9) <= seconds <= self.reached_seconds * (1 + 1e-9)

    def value_at(self, metric, seconds, seed):
        """PT's ``metric`` at ``seconds`` for ``seed``: its own seed's fit, scaled as :meth:`mean_value` scales
        the seeds' mean fit (the local correction, held non-increasing); ``nan`` beyond the ladder."""
        fits = self.fits.get(metric, {})
        if not self.covers(seconds) or seed not in fits:
            return math.nan
        c, floor = fits[seed]
        spp = self.spp_at(seconds)
        corrected = self.corrected_value(metric, spp)
        held = self.mean_value(metric, spp) / corrected if corrected > 0 else 1.0  # an all-zero ladder: no hold
        return fitted_value(c, floor, spp, self.exponent(metric)) * float(held * self.correction(metric, spp)[0])

    def relmse_at(self, seconds, seed):
        """PT's relMSE at ``seconds`` for ``seed``; ``nan`` beyond the ladder."""
        return self.value_at("relmse", seconds, seed)

    def ssim_at(self, seconds, seed):
        """PT's SSIM at ``seconds``: interpolated in log spp on the seed's ladder."""
        return self._interpolated(self.ssim, seconds, seed)

    def flip_at(self, seconds, seed):
        """PT's FLIP at ``seconds``: interpolated in log spp on the seed's ladder."""
        return self._interpolated(self.flip, seconds, seed)

    def _interpolated(self, series, seconds, seed):
        if not self.covers(seconds) or seed not in series:
            return math.nan
        points = series[seed]
        spp = self.spp_at(seconds)
        return float(np.interp(math.log(spp), [math.log(p) for p, _ in points], [v for _, v in points]))

    def mean_fit(self, metric="relmse"):
        """``(c, floor)`` of ``metric`` averaged over the seeds."""
        fits = self.fits[metric].values()
        return float(np.mean([value[0] for value in fits])), float(np.mean([value[1] for value in fits]))

    def spp_for(self, metric, value):
        """PT's spp to reach ``value`` of ``metric`` with the seeds' mean fit, unclamped; ``inf`` at or below its
        fitted floor."""
        c, floor = self.mean_fit(metric)
        if not value > floor:
            return math.inf
        return power_root(c / (value - floor), self.exponent(metric))

    def seconds_for_relmse(self, relmse, metric="relmse"):
        """PT's time to reach ``relmse`` with the seeds' mean fit, unclamped (the model, not a verdict); ``inf``
        at or below its floor. Verdicts use :func:`equal_quality_speedup`, which never reads beyond the ladder."""
        spp = self.spp_for(metric, relmse)
        return math.inf if math.isinf(spp) else self.seconds_at(spp)


def fit_relmse(spps, relmses, exponent=1.0):
    """``(c, floor)`` of ``relMSE = c / spp^exponent + floor`` by relative least squares, ``floor >= 0``,
    ``c >= 0``."""
    spps = np.asarray(spps, np.float64)
    x = 1.0 / spps if exponent == 1.0 else spps ** -float(exponent)
    r = np.asarray(relmses, np.float64)
    design = np.stack([x / r, 1.0 / r], axis=1)
    if len(r) >= 2:
        (c, floor), *_ = np.linalg.lstsq(design, np.ones_like(r), rcond=None)
        if c >= 0 and floor >= 0:
            return float(c), float(floor)
    c = float(np.sum(x / r) / np.sum((x / r) ** 2))  # floor 0
    return max(c, 0.0), 0.0


def spp_power(spp, exponent):
    """``spp ** exponent`` (a number or an array), ``spp`` itself at 1 (the same bytes as before exponents were
    fitted): the denominator of PT's fitted ``c / spp^k + floor``."""
    return spp if exponent == 1.0 else spp ** exponent


def fitted_value(c, floor, spp, exponent=1.0):
    """PT's fitted ``c / spp^exponent + floor`` at ``spp`` (a number or an array): one seed's fit, or the seeds'
    mean (:meth:`BaselineFit.mean_fit`)."""
    return c / spp_power(spp, exponent) + floor


def power_root(value, exponent):
    """``value ** (1 / exponent)``, ``value`` itself at 1: the spp at which ``spp^k`` is ``value``."""
    return value if exponent == 1.0 else value ** (1.0 / exponent)


def relative_residual(spps, relmses, c, floor, exponent=1.0):
    """The root-mean-square relative residual of ``c / spp^exponent + floor`` on a ladder."""
    spps, relmses = np.asarray(spps, np.float64), np.asarray(relmses, np.float64)
    fitted = (c / spps if exponent == 1.0 else c * spps ** -float(exponent)) + floor
    return float(np.sqrt(np.mean((fitted - relmses) ** 2 / np.maximum(relmses, 1e-300) ** 2)))


def fit_exponent(ladders, curved=True):
    """The exponent ``k`` of ``c / spp^k + floor`` shared by the seeds' ladders, and their fits at it.

    Parameters
    ----------
    ladders : dict
        ``{seed: (spps, values)}``, one ladder per seed.
    curved : bool
        False: ``k`` is 1 whatever the residual.

    Returns
    -------
    (float, dict, float)
        ``k``, ``{seed: (c, floor)}`` (:func:`fit_relmse` at ``k``, each
        seed its own) and the median over seeds of their relative residuals.
        ``k`` is the exponent of :data:`EXPONENT_RANGE` (steps of 0.01) of
        least median residual (ties: the larger); 1 unless the ``c / spp +
        floor`` fit leaves more than :data:`CURVED_FIT_LIMIT`, every ladder
        has at least :data:`CURVED_FIT_RUNGS` rungs and the curve at ``k``
        describes the ladders clearly better (a residual of at most
        :data:`CURVE_GAIN` of the line's and at most
        :data:`FIT_RESIDUAL_LIMIT`; a trimmed error that *rises* with spp,
        as on sunlit-room, fits no power and keeps the line, whose residual
        then hands the verdict to the untrimmed relMSE: :func:`headline_metric`).

    Notes
    -----
    An unbiased estimator's relMSE falls as ``1 / spp``. The trimmed relMSE
    need not: where a few pixels per image find a rare bright path
    (sunlight through glass, a glossy floor under a small sun), trimming the
    top 0.1% discards them at low spp, while at high spp more pixels hold
    such paths than trimming removes, so the trimmed value falls more
    slowly (dusk-indirect's ladder: as ``spp^-0.6`` from 8 to 4096 spp). One
    exponent for all seeds keeps their fits averageable
    (:meth:`BaselineFit.mean_fit`); the floor stays each seed's own. Only
    the trimmed metric is fitted so (:func:`fit_baseline`): the untrimmed
    relMSE of an unbiased estimator falls as ``1 / spp``, and a large
    residual there is the noise of its fireflies, not a curve.
    """
    def fits_at(exponent):
        fits = {seed: fit_relmse(spps, values, exponent) for seed, (spps, values) in ladders.items()}
        residual = float(np.median([relative_residual(*ladders[seed], *fits[seed], exponent) for seed in fits]))
        return fits, residual

    fits, residual = fits_at(1.0)
    if not curved or residual <= CURVED_FIT_LIMIT or min(len(spps) for spps, _ in ladders.values()) < CURVED_FIT_RUNGS:
        return 1.0, fits, residual
    best = (residual, 1.0, fits)
    for exponent in np.round(np.arange(EXPONENT_RANGE[1] - 0.01, EXPONENT_RANGE[0] - 0.005, -0.01), 2):
        candidate, candidate_residual = fits_at(float(exponent))
        if candidate_residual < best[0]:
            best = (candidate_residual, float(exponent), candidate)
    if best[0] > FIT_RESIDUAL_LIMIT or best[0] > CURVE_GAIN * residual:
        return 1.0, fits, residual  # no power describes the ladder clearly better than the line
    return best[1], best[2], best[0]


def rung_corrections(ladders, fits, exponent=1.0):
    """PT's local correction of a fit: per rung, the mean over seeds of ``measured / fitted`` and its standard error.

    Parameters
    ----------
    ladders : dict
        ``{seed: (spps, values)}``, as :func:`fit_exponent`.
    fits : dict
        ``{seed: (c, floor)}`` of ``c / spp^exponent + floor``.

    Returns
    -------
    (ndarray, ndarray, ndarray) or None
        The rungs' spp (those every seed ran), the means and their standard
        errors (0 with one seed); None where the seeds share no rung.

    Notes
    -----
    A fitted model reads PT between its rungs with the precision of the
    whole ladder, but where the model does not describe the ladder it reads
    it wrong by the same amount at every seed, and the seeds' spread does not
    show it. Measured on the committed comparisons (the line ``c / spp +
    floor``, 3 seeds): courtyard's trimmed relMSE was 9-11% above the fit at
    64-256 spp in all three seeds (and 13% below it at 8), dusk-indirect's
    12-18% above at 64-128 spp, where the methods' times fell; clean scenes
    (cornell-box, soft-shadows, checker-dof) stay within 1-2%. Multiplying
    the fit by this mean ratio, interpolated in log spp
    (:meth:`BaselineFit.correction`), makes PT's reading at every rung its
    measured mean (exactly where the seeds' fits differ by a factor) while
    keeping each seed's fit between them; its standard error widens the
    verdict's interval (:func:`correction_uncertainty`).
    """
    common = sorted(set.intersection(*(set(spps.tolist()) for spps, _ in ladders.values())))
    if not common:  # seeds that ran no rung in common: no correction
        return None
    ratios = []
    for seed, (spps, values) in ladders.items():
        c, floor = fits[seed]
        lookup = dict(zip(spps.tolist(), values.tolist()))
        measured = np.array([lookup[spp] for spp in common])
        fitted = fitted_value(c, floor, np.array(common, dtype=np.float64), exponent)
        ratios.append(measured / np.maximum(fitted, 1e-300))
    ratios = np.array(ratios)
    means = ratios.mean(axis=0)
    errors = (ratios.std(axis=0, ddof=1) / math.sqrt(len(ratios)) if len(ratios) > 1
              else np.zeros_like(means))
    return np.array(common, dtype=np.float64), means, errors


def fit_time(spps, seconds):
    """``(a, b, residual)``: the Theil-Sen line ``t = a + b spp`` and its robust relative scale.

    ``b`` is the median of the slopes between every pair of rungs and ``a``
    the median of ``t - b spp`` (Sen 1968): one rung slowed by a busy
    machine moves a least-squares line (two demo runs measured PT at 40 spp
    at 0.40 s in one and 0.09 s in the other, and the least-squares
    intercept doubled), not these medians, up to about 29% of the rungs.
    ``residual`` is 1.4826 times the median absolute relative residual (the
    standard deviation's robust estimate), which such a rung does not
    inflate either. A non-increasing line falls back to ``t = b spp``.

    References
    ----------
    Sen, P. K. (1968). Estimates of the regression coefficient based on
    Kendall's tau. Journal of the American Statistical Association 63.
    """
    x, t = np.asarray(spps, np.float64), np.asarray(seconds, np.float64)
    first, second = np.triu_indices(x.size, k=1)
    distinct = x[second] != x[first]
    slope = float(np.median((t[second] - t[first])[distinct] / (x[second] - x[first])[distinct]))
    intercept = float(np.median(t - slope * x))
    if not slope > 0:  # a ladder too short or too noisy to show time growing with spp
        slope, intercept = float(np.median(t / x)), 0.0
    fitted = np.maximum(intercept + slope * x, 1e-12)
    residual = 1.4826 * float(np.median(np.abs(t - fitted) / fitted))
    return intercept, slope, residual


#: A baseline relMSE at or below this at every budget is float rounding: the image has no noise to compare.
NOISE_FREE_RELMSE = 1e-9


def refuse_noise_free_baseline(rows, baseline):
    """Refuse a comparison whose baseline has no error to lose: its relMSE at every budget is at most
    :data:`NOISE_FREE_RELMSE` (float rounding; exactly 0 at some). Every path of such an image finds the same
    value (a camera that sees only emitters or the environment, or only what the kind's paths reach
    deterministically), so error ratios and equal-quality speed-ups would be quotients of rounding."""
    values = [float(row["relmse"]) for row in rows if row["method"] == baseline and row.get("relmse") not in ("", None)]
    if values and max(values) <= NOISE_FREE_RELMSE:
        raise ValueError(f"{baseline}'s relMSE against the reference is at most {max(values):.2g} at every budget: "
                         "its image has no noise (every path of a pixel finds the same value, as where the camera "
                         "sees only emitters or the environment), so no method can be compared with it; frame "
                         "something the kind's paths light, or choose another kind")


def fit_baseline(rows, baseline):
    """The :class:`BaselineFit` of the baseline's rows (at least two spp), or None.

    A rung's time is the median over seeds of its cells' (median) times; the
    line is :func:`fit_time`'s. Every relMSE metric the rows have
    (:func:`judged_metrics`) is fitted per seed. Raises nothing; fewer than
    two budgets give None (no equal-time values).
    """
    pt = [row for row in rows if row["method"] == baseline]
    spps = sorted({row["spp"] for row in pt})
    if len(spps) < 2:
        return None
    times = [float(np.median([row["seconds_total"] for row in pt if row["spp"] == spp])) for spp in spps]
    intercept, slope, residual = fit_time(spps, times)
    metrics = judged_metrics(pt)
    ladders, ssim, flip = {metric: {} for metric in metrics}, {}, {}
    for seed in sorted({row["seed"] for row in pt}):
        seed_rows = sorted((row for row in pt if row["seed"] == seed), key=lambda row: row["spp"])
        if len(seed_rows) >= 2:
            for metric in metrics:
                ladders[metric][seed] = (np.array([row["spp"] for row in seed_rows], dtype=np.float64),
                                         np.array([row[metric] for row in seed_rows], dtype=np.float64))
            ssim[seed] = [(row["spp"], row["ssim"]) for row in seed_rows]
            if all("flip" in row for row in seed_rows):
                flip[seed] = [(row["spp"], row["flip"]) for row in seed_rows]
    fits, residuals, exponents, corrections = {}, {}, {}, {}
    for metric in metrics:
        if ladders[metric]:
            # The trimmed metric's exponent is fitted where its line does not describe the ladder; relMSE's is 1.
            exponent, fits[metric], residuals[metric] = fit_exponent(ladders[metric], curved=metric == HEADLINE_METRIC)
            if exponent != 1.0:
                exponents[metric] = exponent
            correction = rung_corrections(ladders[metric], fits[metric], exponent)
            if correction is not None:
                corrections[metric] = correction
        else:
            fits[metric] = {}
    floors = {metric: float(np.median([row_floor(row, metric) for row in pt])) for metric in metrics}
    # The ladder covers from its fastest to its slowest rung, measured or fitted, whichever reaches further.
    return BaselineFit(intercept=intercept, slope=slope, time_residual=residual, fits=fits,
                       ssim=ssim, flip=flip, spp_range=(spps[0], spps[-1]),
                       reached_seconds=max(intercept + slope * spps[-1], times[-1]),
                       lowest_seconds=min(intercept + slope * spps[0], times[0]), floors=floors,
                       residuals=residuals, exponents=exponents, corrections=corrections)


def add_equal_time_columns(rows, *, baseline="pt"):
    """Add PT's quality at each row's time (``relmse_pt_equal_time``, ``relmse_trimmed_pt_equal_time``,
    ``ssim_pt_equal_time``, ``flip_pt_equal_time``); return the fit.

    Parameters
    ----------
    rows : list of dict
        A comparison's rows (``method``, ``spp``, ``seed``, ``seconds_total``,
        ``relmse``, ``ssim``, and ``relmse_trimmed`` when measured); changed in place.
    baseline : str, optional
        The baseline method's name (the registry's, :func:`sparselt.methods.baseline_name`).

    Returns
    -------
    BaselineFit or None
        None when the baseline ran at fewer than two budgets.

    Notes
    -----
    The columns are ``''`` for the baseline's own rows, without a fit, and
    where the row's time lies beyond the baseline's ladder.

    Raises
    ------
    ValueError
        The baseline's image equals the reference up to float rounding at
        every budget (:func:`refuse_noise_free_baseline`).
    """
    refuse_noise_free_baseline(rows, baseline)
    fit = fit_baseline(rows, baseline)
    metrics = judged_metrics(rows)
    for row in rows:
        for quantity in metrics + ["ssim", "flip"]:
            row[f"{quantity}_pt_equal_time"] = ""
        if row["method"] == baseline or fit is None:
            continue
        values = [(metric, fit.value_at(metric, row["seconds_total"], row["seed"])) for metric in metrics]
        values += [("ssim", fit.ssim_at(row["seconds_total"], row["seed"])),
                   ("flip", fit.flip_at(row["seconds_total"], row["seed"]))]
        for quantity, value in values:
            if math.isfinite(value):
                row[f"{quantity}_pt_equal_time"] = value
    return fit


def _metric_columns(metric):
    return (metric, f"{metric}_ci_low", f"{metric}_ci_high", f"{metric}_pt_equal_time", f"{metric}_ratio",
            f"{metric}_ratio_ci_low", f"{metric}_ratio_ci_high", f"{metric}_verdict")


SUMMARY_COLUMNS = (("method", "spp", "seeds", "seconds_total", "seconds_total_min", "seconds_total_max",
                    "timing_noisy", "timing_uncertainty", "headline_metric", "verdict", "speedup_equal_quality",
                    "speedup_bound", "speedup_ci_low", "speedup_ci_high", "speedup_ci_low_bound",
                    "speedup_ci_high_bound", "pt_ladder_spp", "reference_spp",
                    "reference_spp_needed", "verdicts_disagree", "outlier_share", "outlier_dominated")
                   + _metric_columns("relmse_trimmed") + _metric_columns("relmse")
                   + ("ssim", "ssim_pt_equal_time", "ssim_ratio", "ssim_ratio_ci_low", "ssim_ratio_ci_high",
                      "ssim_verdict", "flip", "flip_pt_equal_time", "flip_ratio", "flip_ratio_ci_low",
                      "flip_ratio_ci_high", "flip_verdict", "luminance_ratio", "luminance_ratio_ci_low",
                      "luminance_ratio_ci_high", "bias_fraction"))
#: What :func:`summarize` writes into every row of a (method, spp) cell (``results.csv``'s derived columns); a
#: row's ``outlier_dominated`` is then its own (its ``outlier_share`` above 0.5).
ROW_SUMMARY_COLUMNS = ("verdict", "speedup_equal_quality", "speedup_bound", "outlier_dominated")
#: Every column :func:`judge` writes into the rows (never read back: a re-judged folder recomputes them).
DERIVED_ROW_COLUMNS = (tuple(f"{metric}_pt_equal_time" for metric in RELMSE_METRICS)
                       + ("ssim_pt_equal_time", "flip_pt_equal_time")
                       + tuple(f"{metric}_ratio" for metric in RELMSE_METRICS) + ROW_SUMMARY_COLUMNS
                       + ("bias_fraction",))


def summarize(rows, fit, *, baseline="pt", reference_spp=None):
    """One record per (method, spp) with :data:`SUMMARY_COLUMNS` (``summary.csv``; and ``headline_exponent``, the
    exponent of PT's headline fit, where it is not 1: :func:`fit_exponent`); also fills the rows'
    per-metric ratios (``relmse_ratio``, ``relmse_trimmed_ratio``: debiased, against PT at the row's time) and
    :data:`ROW_SUMMARY_COLUMNS` (their intervals only in the summary).

    ``reference_spp`` (the reference's samples per pixel; default the rows' ``reference_spp``) names the
    reference a reference-limited cell would need.
    """
    metrics = judged_metrics(rows)
    headline = headline_metric(rows, fit)
    if reference_spp is None:
        reference_spp = next((row["reference_spp"] for row in rows if row.get("reference_spp") not in ("", None)),
                             None)
    summary = []
    for method, spp, group in method_spp_groups(rows):
        record = dict.fromkeys(SUMMARY_COLUMNS, "")  # every record has every column, in order
        record.update(method=method, spp=spp, seeds=len(group), headline_metric=headline,
                      reference_spp=reference_spp if reference_spp is not None else "")
        record["seconds_total"] = group_mean(group, "seconds_total")
        record["seconds_total_min"] = min(row.get("seconds_total_min", row["seconds_total"]) for row in group)
        record["seconds_total_max"] = max(row.get("seconds_total_max", row["seconds_total"]) for row in group)
        record["timing_noisy"] = any(bool(row.get("timing_noisy")) for row in group)
        for metric in metrics:
            record[metric], record[f"{metric}_ci_low"], record[f"{metric}_ci_high"] = mean_interval(
                [row[metric] for row in group])
        if all(row.get("outlier_share") not in ("", None) for row in group):
            record["outlier_share"] = group_mean(group, "outlier_share")
            record["outlier_dominated"] = bool(record["outlier_share"] > OUTLIER_DOMINATED_SHARE)
        record["ssim"] = group_mean(group, "ssim")
        record["flip"] = group_mean(group, "flip") if all("flip" in row for row in group) else ""
        if all(row.get("luminance_ratio") not in ("", None) for row in group):
            record["luminance_ratio"], record["luminance_ratio_ci_low"], record["luminance_ratio_ci_high"] = (
                mean_interval([row["luminance_ratio"] for row in group]))
        _compare_with_baseline(record, group, fit, method == baseline, metrics, headline)
        if fit is not None and fit.exponent(headline) != 1.0:  # only where fitted (the report notes it)
            record["headline_exponent"] = fit.exponent(headline)
        summary.append(record)
        for row in group:
            for metric in metrics:
                floor = row_floor(row, metric)
                pt_value = row.get(f"{metric}_pt_equal_time")
                row[f"{metric}_ratio"] = ((row[metric] - floor) / (pt_value - floor)
                                          if pt_value not in ("", None) and pt_value - floor > 0 else "")
            for column in ROW_SUMMARY_COLUMNS:
                row[column] = record[column]
            if row.get("outlier_share") not in ("", None):  # each run marked on its own share
                row["outlier_dominated"] = bool(row["outlier_share"] > OUTLIER_DOMINATED_SHARE)
    return summary


def timing_uncertainty(group, fit):
    """The relative uncertainty of a cell's time: its repeats' spread and PT's time-fit residual, combined.

    ``d = sqrt(s^2 + e^2)``: ``s`` the largest half-range of the repeats
    relative to their median over the cell's seeds, ``e`` the root-mean-square
    relative residual of PT's ``a + b spp`` fit. Sub-second timings on shared
    machines move by tens of percent between runs; the seeds' spread alone
    does not see it.
    """
    spreads = [(row.get("seconds_total_max", row["seconds_total"]) - row.get("seconds_total_min", row["seconds_total"]))
               / (2 * row["seconds_total"]) for row in group if row["seconds_total"] > 0]
    spread = max(spreads, default=0.0)
    return float(math.hypot(spread, fit.time_residual))


def correction_uncertainty(fit, metric, seconds, seeds):
    """The log half-width that PT's local correction adds to a ratio's 95% interval at ``seconds``:
    ``t_(seeds - 1) * log(1 + s / g)``, ``g`` the correction and ``s`` its standard error there
    (:meth:`BaselineFit.correction`); 0 with fewer than two seeds or no correction."""
    if seeds < 2:
        return 0.0
    factor, error = fit.correction(metric, fit.spp_at(seconds))
    if not (factor > 0 and error > 0):
        return 0.0
    return t_quantile(seeds - 1) * math.log1p(float(error) / float(factor))


def equal_quality_speedup(fit, metric, ratio, seconds, floor):
    """PT's time to reach ``ratio`` times its own debiased ``metric`` at ``seconds``, over ``seconds``.

    Parameters
    ----------
    fit : BaselineFit
    metric : str
        A relMSE metric of ``fit.fits``.
    ratio : float
        The method's debiased value over PT's at the method's time (or a bound of its interval).
    seconds : float
        The method's (mean) time.
    floor : float
        The reference's floor in ``metric``.

    Returns
    -------
    (float, str)
        The speed-up and its bound: ``''`` within PT's ladder; ``'>'`` when
        PT would need more than its ladder's largest spp (the value is then
        the speed-up at that rung: a lower bound, never infinite); ``'<'``
        when it would need fewer than its smallest.

    Notes
    -----
    PT's debiased value needed is ``ratio * (m(spp(seconds)) - floor)``, ``m``
    its seeds' mean fit locally corrected and held non-increasing
    (:meth:`BaselineFit.mean_value`), reached at the least spp where ``m``
    falls to ``floor`` plus it (:meth:`BaselineFit.spp_reaching`). At ``ratio
    = 1`` that is PT's own spp at ``seconds`` (or the start of a stretch where
    ``m`` is flat) and the speed-up is 1: the speed-up is a non-increasing
    function of the ratio alone, so its interval is the ratio's interval
    mapped through it, and the two verdicts agree.
    """
    own = float(fit.mean_value(metric, fit.spp_at(seconds))) - floor
    spp, bound = fit.spp_reaching(metric, np.array([floor + ratio * own]))
    return fit.seconds_at(float(spp[0])) / seconds, str(bound[0])


def _compare_with_baseline(record, group, fit, is_baseline, metrics, headline):
    record.update(verdict="baseline" if is_baseline else "no PT value")
    if is_baseline or fit is None:
        return
    for metric in metrics:
        _judge_metric(record, group, fit, metric)
    record["verdict"] = record.get(f"{headline}_verdict") or "no PT value"
    if record["verdict"] == "reference-limited":
        record["reference_spp_needed"] = _reference_needed(record, group, fit, headline)
    others = {record.get(f"{metric}_verdict") for metric in metrics} | {record.get("flip_verdict")}
    others.discard("")
    record["verdicts_disagree"] = len(others) > 1
    pt_ssim = [row.get("ssim_pt_equal_time") for row in group]
    if not any(value in ("", None) for value in pt_ssim):
        record["ssim_pt_equal_time"] = float(np.mean(pt_ssim))
        ratio, low, high = ratio_interval(pt_ssim, [row["ssim"] for row in group])  # PT over method: < 1 is better
        record.update(ssim_ratio=ratio, ssim_ratio_ci_low=low, ssim_ratio_ci_high=high,
                      ssim_verdict=verdict(low, high))
    pt_flip = [row.get("flip_pt_equal_time") for row in group]
    if record["flip"] != "" and not any(value in ("", None) for value in pt_flip) and min(pt_flip) > 0:
        record["flip_pt_equal_time"] = float(np.mean(pt_flip))
        ratio, low, high = ratio_interval([row["flip"] for row in group], pt_flip)  # method over PT: < 1 is better
        record.update(flip_ratio=ratio, flip_ratio_ci_low=low, flip_ratio_ci_high=high,
                      flip_verdict=verdict(low, high))
        record["verdicts_disagree"] = len(others | {record["flip_verdict"]}) > 1
    ratio = record.get(f"{headline}_ratio")
    if record["verdict"] in ("wins", "loses", "within noise", "one seed") and isinstance(ratio, float):
        floor = row_floor(group[0], headline)
        seconds = record["seconds_total"]
        record["speedup_equal_quality"], record["speedup_bound"] = equal_quality_speedup(
            fit, headline, ratio, seconds, floor)
        if record["speedup_bound"]:
            record["pt_ladder_spp"] = fit.spp_range[1] if record["speedup_bound"] == ">" else fit.spp_range[0]
        low, high = record[f"{headline}_ratio_ci_low"], record[f"{headline}_ratio_ci_high"]
        if isinstance(low, float) and math.isfinite(low) and math.isfinite(high):
            # A lower ratio is a larger speed-up: the interval's bounds swap.
            record["speedup_ci_low"], record["speedup_ci_low_bound"] = equal_quality_speedup(
                fit, headline, high, seconds, floor)
            record["speedup_ci_high"], record["speedup_ci_high_bound"] = equal_quality_speedup(
                fit, headline, low, seconds, floor)


def _judge_metric(record, group, fit, metric):
    """``metric``'s ratio to PT at equal time, its interval (widened by the timing's uncertainty) and verdict."""
    pt_values = [row.get(f"{metric}_pt_equal_time") for row in group]
    if any(value in ("", None) for value in pt_values):
        return
    record[f"{metric}_pt_equal_time"] = float(np.mean(pt_values))
    floors = {row_floor(row, metric) for row in group} if metric == "relmse" else {0.0}
    if len(floors) != 1:
        raise ValueError(f"the seeds of {record.get('method')!r} at spp {record.get('spp')} were measured against "
                         f"references of different floors {sorted(floors)}; a comparison has one reference")
    own_floors = np.array([row_floor(row, metric) for row in group])
    measured = np.array([row[metric] for row in group], dtype=np.float64)
    pt_measured = np.array(pt_values, dtype=np.float64)
    numerator, denominator = measured - own_floors, pt_measured - own_floors
    limited = (np.any(numerator <= 0) or np.any(denominator <= 0)
               or own_floors.mean() >= REFERENCE_LIMITED_SHARE * measured.mean()
               or own_floors.mean() >= REFERENCE_LIMITED_SHARE * pt_measured.mean())
    if limited:
        # Within the reference's own noise: the debiased values say nothing; no win, loss or speed-up is claimed.
        record[f"{metric}_verdict"] = "reference-limited"
        return
    ratio, low, high = ratio_interval(numerator, denominator)
    # The time is uncertain too: PT's value is read at the method's time t, which moves between runs. Read it
    # at t / (1 + d) and t (1 + d), d the timing uncertainty, and keep the wider bounds.
    spread = timing_uncertainty(group, fit)
    record["timing_uncertainty"] = spread
    if math.isfinite(low) and spread > 0:
        late = [fit.value_at(metric, min(row["seconds_total"] * (1 + spread), fit.reached_seconds), row["seed"])
                - row_floor(row, metric) for row in group]
        early = [fit.value_at(metric, max(row["seconds_total"] / (1 + spread), fit.lowest_seconds), row["seed"])
                 - row_floor(row, metric) for row in group]
        if all(value > 0 for value in early + late):
            low = min(low, ratio_interval(numerator, early)[1])
            high = max(high, ratio_interval(numerator, late)[2])
    # PT's local correction is the mean of its seeds' rungs: its own uncertainty (relative standard error ``s`` at
    # the method's spp, ``t`` quantile) joins the interval's half-widths on the log scale, in quadrature.
    extra = correction_uncertainty(fit, metric, record["seconds_total"], len(group))
    if math.isfinite(low) and extra > 0:
        low = ratio * math.exp(-math.hypot(math.log(ratio / low), extra))
        high = ratio * math.exp(math.hypot(math.log(high / ratio), extra))
    record.update({f"{metric}_ratio": ratio, f"{metric}_ratio_ci_low": low, f"{metric}_ratio_ci_high": high,
                   f"{metric}_verdict": verdict(low, high)})


def _reference_needed(record, group, fit, metric):
    """The reference spp whose floor would resolve a reference-limited cell: the floor at most half the smaller
    of the method's and PT's measured means (:data:`REFERENCE_LIMITED_SHARE`), from the floor's 1/spp law;
    ``''`` without a reference spp or a floor."""
    floor = float(np.mean([row_floor(row, metric) for row in group]))
    spp = record.get("reference_spp")
    if not floor > 0 or spp in ("", None):
        return ""
    debiased = min(record[metric], record[f"{metric}_pt_equal_time"]) - floor
    if not debiased > 0:
        # At or below the reference's noise: at least a twice longer reference; the rerun says how much more.
        return reference_spp_for_floor(floor, int(spp), floor / 2)
    return reference_spp_for_floor(floor, int(spp), debiased * REFERENCE_LIMITED_SHARE / (1 - REFERENCE_LIMITED_SHARE))


def judge(rows, *, baseline="pt", reference_spp=None, bias=None):
    """The equal-time protocol on a comparison's rows: PT's fits and the rows' equal-time columns
    (:func:`add_equal_time_columns`), the summary (:func:`summarize`) and the bias fractions
    (:func:`add_bias_fractions`, from ``bias``, a :func:`bias_record`). The one call of ``compare``,
    :func:`sparselt.load_comparison` and the committed experiments' re-judging.

    Returns
    -------
    (BaselineFit or None, list of dict)
    """
    fit = add_equal_time_columns(rows, baseline=baseline)
    summary = summarize(rows, fit, baseline=baseline, reference_spp=reference_spp)
    add_bias_fractions(summary, bias, rows)
    return fit, summary


def fit_record(fit):
    """PT's fits as ``compare.json``'s ``pt_fit`` holds them (None without a fit)."""
    if fit is None:
        return None
    record = {"intercept_seconds": fit.intercept, "seconds_per_spp": fit.slope,
              "time_relative_residual": fit.time_residual, "spp_range": list(fit.spp_range)}
    for metric, fits in fit.fits.items():
        record[f"{metric}_per_seed"] = {str(seed): {"c": c, "floor": floor} for seed, (c, floor) in fits.items()}
        record[f"{metric}_relative_residual"] = fit.residuals.get(metric)
        if fit.exponent(metric) != 1.0:  # written only where fitted: c / spp^k + floor
            record[f"{metric}_exponent"] = fit.exponent(metric)
        if metric in fit.corrections:
            record[f"{metric}_rung_correction"] = [
                {"spp": float(spp), "mean": float(mean), "standard_error": float(error)}
                for spp, mean, error in zip(*fit.corrections[metric])]
    return record


#: The bias test's level and multiple-comparison correction in every comparison (:func:`bias_record`).
BIAS_LEVEL = 0.01
BIAS_CORRECTION = "benjamini-hochberg"


def bias_record(rows, image_of, reference, reference_variance, reference_degrees_of_freedom):
    """The bias test of every (method, spp) with at least two seeds: ``compare.json``'s ``bias`` record.

    Parameters
    ----------
    rows : list of dict
        The comparison's rows (their ``method``, ``spp`` and ``seed``).
    image_of : callable
        ``image_of(row)``: the row's image, ``(height, width, 3)``.
    reference : ndarray
        The reference image.
    reference_variance : ndarray or None
        The per-pixel variance of the reference's mean; None (a reference of one pass) takes it as exact.
    reference_degrees_of_freedom : int or None
        Its passes minus 1; None with ``reference_variance`` None.

    Returns
    -------
    dict
        ``level``, ``correction``, ``reference_degrees_of_freedom`` and ``cells``: one
        ``{"method", "spp", "seeds", "bias_fraction"}`` per tested (method, spp).

    Notes
    -----
    :func:`sparselt.analysis.bias.pixel_bias_test` of the method's images over seeds against the reference:
    Welch's t-test per pixel, Benjamini-Hochberg at 1% (Jung et al. 2020, JCGT 9(2)).
    """
    from ..analysis.bias import pixel_bias_test

    cells = []
    for method, spp, group in method_spp_groups(rows):
        if len(group) < 2:
            continue
        result = pixel_bias_test(np.stack([image_of(row) for row in group]), reference, reference_variance,
                                 reference_degrees_of_freedom=reference_degrees_of_freedom, level=BIAS_LEVEL,
                                 correction=BIAS_CORRECTION)
        cells.append({"method": method, "spp": spp, "seeds": len(group), "bias_fraction": result.biased_fraction})
    return {"level": BIAS_LEVEL, "correction": BIAS_CORRECTION,
            "reference_degrees_of_freedom": reference_degrees_of_freedom, "cells": cells}


def add_bias_fractions(summary, record, rows=()):
    """Fill the summary's and the ``rows``' ``bias_fraction`` from a :func:`bias_record` (None: a folder without
    one, left empty).

    A cell whose seeds changed since the record was made (a rerun that added seeds) is left empty.
    """
    if not record:
        return summary
    fractions = {(cell["method"], cell["spp"], cell["seeds"]): cell["bias_fraction"] for cell in record["cells"]}
    seeds = {}
    for entry in summary:
        entry["bias_fraction"] = fractions.get((entry["method"], entry["spp"], entry["seeds"]), "")
        seeds[entry["method"], entry["spp"]] = entry["bias_fraction"]
    for row in rows:
        row["bias_fraction"] = seeds.get((row["method"], row["spp"]), "")
    return summary


__all__ = ["BIAS_CORRECTION", "BIAS_LEVEL", "CONFIDENCE", "FIT_RESIDUAL_LIMIT", "HEADLINE_METRIC", "NOISY_TIMING_RATIO",
           "OUTLIER_DOMINATED_SHARE", "REFERENCE_LIMITED_SHARE", "RELMSE_METRICS", "ROW_SUMMARY_COLUMNS",
           "SUMMARY_COLUMNS", "VERDICTS", "DERIVED_ROW_COLUMNS", "BaselineFit", "add_bias_fractions", "add_equal_time_columns", "bias_record",
           "correction_uncertainty", "equal_quality_speedup", "fit_baseline", "fit_exponent", "fit_record", "fitted_value", "power_root", "rung_corrections", "spp_power", "judge", "fit_relmse", "fit_time", "headline_metric", "judged_metrics",
           "mean_interval", "ratio_interval", "row_floor", "summarize",
           "timing_uncertainty", "verdict"]
