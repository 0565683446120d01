"""Fault classification from the residual's shape over a window, and the label of an alarm.

Fault families follow Wan2018 Table II and the project's fault profiles: bias (step, then
flat), drift (slow ramp), runaway (fast ramp, possibly up to a limit), oscillation (periodic),
stuck/jamming (the measurement stops moving), noise (variance increase, zero mean).

:func:`classify_residual` fits each family's model to one window (oldest first) and decides,
in this order (each test is a documented, tunable parameter in :class:`ClassifierShape`;
``a_min = min_fault_sigma * noise_sigma`` is the smallest fault worth naming):

1. stuck: the *measurement* (when given) has std < ``stuck_std_ratio * noise_sigma``,
   i.e. less than a healthy sensor's own noise.  Magnitude: mean residual of the last quarter.
2. The trend models, each least squares with its change point(s) searched exhaustively:
   *step* (two levels, one change point: a bias whose onset is in the window) and *ramp* (the
   better of a level followed by a ramp -- a drift or runaway starting in the window, or one
   older than it -- and a ramp followed by a level -- a runaway that reached its limit).
3. oscillation: after removing the better trend model, the strongest FFT bin carries more than
   ``osc_power_fraction`` of the variance (it is periodic) and more than ``osc_power_fraction``
   of the fault's power, the oscillation's plus the mean square of the trend it rides on (it
   is the fault, not a ripple on a bias or a ramp), the window holds at least
   ``osc_min_cycles`` periods and the amplitude ``sqrt(2) * std`` exceeds ``a_min``.
   Magnitude: amplitude.  Detrending with the step (not a straight line) keeps a bias onset in
   mid-window from reading as one cycle of a sawtooth.
4. step vs ramp: the step leaves less squared residual than the ramp and its height exceeds
   ``a_min``: bias, magnitude = level after the step.
5. ramp: its change over the window exceeds ``a_min``: runaway if ``|slope| >=
   runaway_rate``, else drift.  Magnitude: fitted value at the last sample; ``rate_per_s``.
6. flat offset: ``|mean| > a_min``: bias (onset before the window), magnitude = mean.
7. noise: std > ``noise_std_ratio * noise_sigma`` with zero mean: magnitude = excess std
   ``sqrt(std^2 - noise_sigma^2)``.
8. otherwise unknown.

**Confidence** of the result, in [0, 1]: the closest call on its decision path.  Every test
taken on the way (passed or failed) has a margin ``|ln(x / threshold)| / ln(certain_ratio)``,
capped at 1 (a test passed or failed by a factor ``certain_ratio`` is certain); the confidence
is the smallest of them, so a bias whose step fits only slightly better than a ramp, or a
drift whose rate is near the runaway rate, says so.  Unknown has confidence 0.

**The label of an alarm** (:class:`LabelHysteresis`): the type is decided at the raise and
changed only on decisive evidence.  A different type must win every re-classification over
``relabel_windows`` classifier windows of new data (consecutive re-classifications overlap: with
a 10 s window every 2.5 s, one window of new data is 5 wins in a row), each decisively: the held
type's model leaves at least
``relabel_fit_ratio`` times the squared residual of the new type's model on the same window;
between drift and runaway (one model) the window must show a ramp (the ramp model decisively
better than a level) whose fitted rate lies beyond the runaway rate by the factor
``relabel_rate_ratio``.  A window that disagrees without being decisive (a bias
whose window looks like one cycle of an oscillation; a runaway at its limit, which leaves a
level that the ramp model explains as well as the step) leaves the label and restarts the
count.  While a rival wins, the label's confidence falls in proportion to the wins it needs.
No-data is an observation, not a shape: it is taken at once.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from gcs_monitor.core.params import param
from gcs_monitor.fdi.events import OBSERVED_TYPES, FaultType


@dataclass(frozen=True, slots=True)
class ClassifierShape:
    """The shape tests of the classifier and the hysteresis of alarm labels, common to every
    channel (project choices, see the module doc); ``[classifier]`` in the configuration."""

    min_fault_sigma: float = param(4.0, "smallest fault worth naming, in noise sigmas (a_min)",
                                   positive=True)
    stuck_std_ratio: float = param(0.2, "a measurement whose std is below this fraction of "
                                   "the noise sigma is stuck", positive=True)
    osc_power_fraction: float = param(0.5, "share of the detrended variance, and of the "
                                      "fault's power with the trend it rides on, the strongest "
                                      "frequency must carry for an oscillation",
                                      positive=True)
    osc_min_cycles: float = param(2.0, "periods an oscillation must show in the window",
                                  positive=True)
    noise_std_ratio: float = param(2.0, "std above this many noise sigmas with zero mean is a "
                                   "noise fault", positive=True)
    certain_ratio: float = param(2.0, "a classifier test passed or failed by this factor is "
                                 "certain (confidence 1); the confidence of a type is the "
                                 "closest call on its decision path", positive=True)
    relabel_windows: float = param(1.0, "a new fault type must win every re-classification "
                                   "over this many classifier windows (history_s) of new "
                                   "data, each decisively, before it replaces the type decided "
                                   "at the raise", positive=True)
    relabel_fit_ratio: float = param(2.0, "decisive: the held type's model leaves at least "
                                     "this many times the squared residual of the new type's "
                                     "model on the window", positive=True)
    relabel_rate_ratio: float = param(1.5, "drift <-> runaway: decisive when the fitted rate "
                                      "is this factor above the runaway rate (for runaway) or "
                                      "below it (for drift)", positive=True)

    def __post_init__(self) -> None:
        for name in ("certain_ratio", "relabel_fit_ratio", "relabel_rate_ratio"):
            if not getattr(self, name) > 1.0:
                raise ValueError(f"classifier.{name} must be > 1, got {getattr(self, name)}")


_SHAPE = ClassifierShape()


@dataclass(frozen=True, slots=True)
class ClassifierParams:
    """Classification thresholds for one channel.

    noise_sigma : healthy residual 1-sigma, channel SI unit
    runaway_rate_per_s : slope at and above which a ramp is a runaway, SI/s (Wan2018
        Table II runaways start at 0.2 deg/s for AoA and 0.5 kt/s for CAS)
    the others : :class:`ClassifierShape`
    """

    noise_sigma: float
    runaway_rate_per_s: float
    min_fault_sigma: float = _SHAPE.min_fault_sigma
    stuck_std_ratio: float = _SHAPE.stuck_std_ratio
    osc_power_fraction: float = _SHAPE.osc_power_fraction
    osc_min_cycles: float = _SHAPE.osc_min_cycles
    noise_std_ratio: float = _SHAPE.noise_std_ratio
    certain_ratio: float = _SHAPE.certain_ratio
    relabel_windows: float = _SHAPE.relabel_windows
    relabel_fit_ratio: float = _SHAPE.relabel_fit_ratio
    relabel_rate_ratio: float = _SHAPE.relabel_rate_ratio

    def __post_init__(self) -> None:
        if not self.noise_sigma > 0.0:
            raise ValueError(f"noise_sigma must be > 0, got {self.noise_sigma}")
        if not self.runaway_rate_per_s > 0.0:
            raise ValueError(f"runaway_rate_per_s must be > 0, got {self.runaway_rate_per_s}")

    @classmethod
    def of(cls, noise_sigma: float, runaway_rate_per_s: float,
           shape: ClassifierShape = _SHAPE) -> ClassifierParams:
        """The parameters of one channel with the common shape tests."""
        common = {f.name: getattr(shape, f.name) for f in dataclasses.fields(ClassifierShape)}
        return cls(noise_sigma, runaway_rate_per_s, **common)


@dataclass(frozen=True, slots=True)
class TypeFit:
    """One fault type's model fitted to the window.

    sse : squared residual the model leaves, SI^2 (NaN for types judged by a statistic rather
        than a residual model: stuck, noise)
    magnitude, rate_per_s, frequency_hz : what the type reports on this window (see
        :class:`Classification`)
    """

    sse: float
    magnitude: float
    rate_per_s: float = math.nan
    frequency_hz: float = math.nan


@dataclass(frozen=True, slots=True)
class Classification:
    """Result of :func:`classify_residual`.

    magnitude : signed fault value at the end of the window (bias, drift, runaway, stuck),
        oscillation amplitude, or excess noise std; SI
    rate_per_s : fitted slope, SI/s (drift/runaway; the ramp fit's slope otherwise)
    frequency_hz : dominant frequency (oscillation), else NaN
    confidence : in [0, 1], the closest call on the decision path (module doc)
    fits : every type's model on the same window (what :class:`LabelHysteresis` compares)
    """

    fault_type: FaultType
    magnitude: float
    rate_per_s: float = math.nan
    frequency_hz: float = math.nan
    confidence: float = 0.0
    fits: Mapping[FaultType, TypeFit] = field(default_factory=dict)


def _best_step(r: np.ndarray) -> tuple[float, float, float, int]:
    """Least-squares two-level fit with one change point: (sse, level_before, level_after, k).

    O(N) with cumulative sums; the change point k is the first index of the second level.
    """
    n = r.size
    c1 = np.cumsum(r)
    c2 = np.cumsum(r * r)
    k = np.arange(1, n)  # split sizes of the first segment
    s1, q1 = c1[:-1], c2[:-1]
    s2, q2 = c1[-1] - s1, c2[-1] - q1
    sse = (q1 - s1 * s1 / k) + (q2 - s2 * s2 / (n - k))
    j = int(np.argmin(sse))
    kk = j + 1
    return float(sse[j]), float(s1[j] / kk), float(s2[j] / (n - kk)), kk


@dataclass(frozen=True, slots=True)
class _Ramp:
    """Best ramp model: value ``a + b * x(t)`` with a hinge at ``t_k``."""

    sse: float
    a: float
    b: float
    change: float  # b times the duration of the ramp inside the window, SI
    end: float  # fitted value at the last sample, SI
    fitted: np.ndarray


def _regress(sx: np.ndarray, sxx: np.ndarray, sxr: np.ndarray, n: int, sr: float,
             srr: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """SSE, intercept and slope of ``r ~ a + b x`` per candidate, from the sums of x, x^2, x r
    (arrays over candidates) and of r, r^2; SSE is +inf where x has no spread."""
    sxx_c = sxx - sx * sx / n
    sxr_c = sxr - sx * sr / n
    ok = sxx_c > 1e-12 * np.maximum(sxx, 1e-300)
    b = np.where(ok, sxr_c / np.where(ok, sxx_c, 1.0), 0.0)
    sse = np.where(ok, (srr - sr * sr / n) - b * sxr_c, np.inf)
    a = (sr - b * sx) / n
    return np.maximum(sse, 0.0), a, b


_MIN_RAMP_N = 4  # samples a ramp spans at least (the classifier's smallest window)


def _best_ramp(t: np.ndarray, r: np.ndarray) -> _Ramp:
    """Least-squares ramp with one hinge, both ways: a level then a ramp from ``t_k``
    (``x = max(0, t - t_k)``; ``t_k = t_0`` is a straight line) and a ramp up to ``t_k`` then
    a level (``x = min(t, t_k)``, a runaway at its limit). O(N) with cumulative sums."""
    n = r.size
    ct, ctt, ctr, cr = np.cumsum(t), np.cumsum(t * t), np.cumsum(t * r), np.cumsum(r)
    sr, srr = float(cr[-1]), float(r @ r)
    # level then ramp, hinge at k = 0 .. n-5: at least _MIN_RAMP_N samples on the ramp (a hinge
    # on the last two samples would fit their noise)
    k = np.arange(max(1, n - _MIN_RAMP_N))
    tk = t[k]
    m = (n - 1 - k).astype(np.float64)
    t1, t2 = ct[-1] - ct[k], ctt[-1] - ctt[k]
    tr, rs = ctr[-1] - ctr[k], cr[-1] - cr[k]
    sse_h, a_h, b_h = _regress(t1 - m * tk, t2 - 2.0 * tk * t1 + m * tk * tk, tr - tk * rs,
                               n, sr, srr)
    # ramp then level, hinge at k = 3 .. n-1 (k = n-1 is the line again)
    k2 = np.arange(min(_MIN_RAMP_N - 1, n - 1), n)
    tk2 = t[k2]
    m2 = (n - 1 - k2).astype(np.float64)
    sse_p, a_p, b_p = _regress(ct[k2] + m2 * tk2, ctt[k2] + m2 * tk2 * tk2,
                               ctr[k2] + tk2 * (cr[-1] - cr[k2]), n, sr, srr)
    jh, jp = int(np.argmin(sse_h)), int(np.argmin(sse_p))
    if sse_h[jh] <= sse_p[jp]:
        a, b, x = float(a_h[jh]), float(b_h[jh]), np.maximum(0.0, t - t[jh])
        change = b * (t[-1] - t[jh])
        sse = float(sse_h[jh])
    else:
        a, b, x = float(a_p[jp]), float(b_p[jp]), np.minimum(t, t[k2[jp]])
        change = b * (t[k2[jp]] - t[0])
        sse = float(sse_p[jp])
    fitted = a + b * x
    return _Ramp(sse, a, b, change, float(fitted[-1]), fitted)


class _Path:
    """Margins of the tests on a decision path (module doc, "Confidence")."""

    __slots__ = ("log_certain", "margins")

    def __init__(self, certain_ratio: float) -> None:
        self.log_certain = math.log(certain_ratio)
        self.margins: list[float] = []

    def margin(self, x: float, threshold: float) -> float:
        if not (x > 0.0 and threshold > 0.0) or x == math.inf:
            return 1.0  # zero or infinite against a finite threshold: as far as it gets
        return min(1.0, abs(math.log(x / threshold)) / self.log_certain)

    def passed(self, *pairs: tuple[float, float]) -> None:
        """Every (statistic, threshold) of a passed test held: the test's margin is the
        smallest."""
        self.margins.append(min(self.margin(x, th) for x, th in pairs))

    def failed(self, *pairs: tuple[float, float, bool]) -> None:
        """(statistic, threshold, held) of a failed test: it failed by its clearest failing
        condition."""
        self.margins.append(max(self.margin(x, th) for x, th, held in pairs if not held))

    def confidence(self) -> float:
        return min(self.margins, default=1.0)


def classify_residual(
    residual: Sequence[float] | np.ndarray,
    dt_s: float,
    params: ClassifierParams,
    *,
    measured: Sequence[float] | np.ndarray | None = None,
) -> Classification:
    """Classify a fault from a window of residuals (oldest first) sampled every ``dt_s``.

    Parameters
    ----------
    residual : (N,) residual (measurement minus reference), channel SI unit; N >= 4
    dt_s : sample interval, s
    params : thresholds
    measured : (N,) the raw measurement over the same window, for the stuck test
    """
    r = np.asarray(residual, dtype=np.float64)
    n = r.size
    if n < 4:
        raise ValueError(f"need at least 4 samples to classify, got {n}")
    sigma = params.noise_sigma
    a_min = params.min_fault_sigma * sigma
    t = np.arange(n, dtype=np.float64) * dt_s
    path = _Path(params.certain_ratio)
    nan = math.nan

    ramp = _best_ramp(t, r)
    sse_step, lvl0, lvl1, k_step = _best_step(r)
    step_height = abs(lvl1 - lvl0)
    mean = float(np.mean(r))
    std = float(np.std(r))
    excess = math.sqrt(max(std * std - sigma * sigma, 0.0))
    step_wins = sse_step < ramp.sse and step_height > a_min
    bias_mag = lvl1 if step_wins else mean
    ramp_fit = TypeFit(ramp.sse, ramp.end, ramp.b)
    fits: dict[FaultType, TypeFit] = {
        FaultType.BIAS: TypeFit(sse_step, bias_mag, ramp.b),
        FaultType.DRIFT: ramp_fit, FaultType.RUNAWAY: ramp_fit,
        FaultType.NOISE: TypeFit(nan, excess, ramp.b),
    }

    def result(kind: FaultType, magnitude: float, *, frequency_hz: float = nan) -> Classification:
        conf = path.confidence() if kind is not FaultType.UNKNOWN else 0.0
        return Classification(kind, magnitude, rate_per_s=ramp.b, frequency_hz=frequency_hz,
                              confidence=conf, fits=fits)

    if measured is not None:
        m = np.asarray(measured, dtype=np.float64)
        if m.size >= 4:
            std_m = float(np.std(m))
            stuck_th = params.stuck_std_ratio * sigma
            fits[FaultType.STUCK] = TypeFit(nan, float(np.mean(r[-max(4, n // 4):])), ramp.b)
            if std_m < stuck_th:
                path.passed((std_m, stuck_th))
                return result(FaultType.STUCK, fits[FaultType.STUCK].magnitude)
            path.failed((std_m, stuck_th, False))

    # oscillation: dominant spectral line of the residual left by the better trend model
    if sse_step < ramp.sse:
        trend = np.where(np.arange(n) < k_step, lvl0, lvl1)
        sse_trend = sse_step
    else:
        trend, sse_trend = ramp.fitted, ramp.sse
    e = r - trend
    var_e = sse_trend / n
    spec = np.abs(np.fft.rfft(e)) ** 2
    spec[0] = 0.0
    if spec.size > 2 and var_e > 0.0:
        kpk = int(np.argmax(spec))
        # Parseval: a bin k (0 < k < N/2) holds 2|X_k|^2 / N^2 of the variance
        frac = 2.0 * float(spec[kpk]) / (n * n) / var_e
        # a line between bins leaks into the neighbour: count the two strongest adjacent bins
        if 0 < kpk < spec.size - 1:
            frac += 2.0 * float(max(spec[kpk - 1], spec[kpk + 1])) / (n * n) / var_e
        frac = min(frac, 1.0)
        amp = math.sqrt(2.0 * var_e)
        freq = kpk / (n * dt_s)
        fits[FaultType.OSCILLATION] = TypeFit(sse_trend * (1.0 - frac), amp, ramp.b, freq)
        f0 = params.osc_power_fraction
        p_line = frac * var_e
        p_trend = float(trend @ trend) / n  # the healthy residual has zero mean
        dominance = p_line / (p_line + p_trend)
        conds = ((frac, f0, frac > f0), (dominance, f0, dominance > f0),
                 (amp, a_min, amp > a_min))
        if all(held for _, _, held in conds) and kpk >= params.osc_min_cycles:
            path.passed(*((x, th) for x, th, _ in conds))
            # a level under an oscillation of >= 2 cycles: the mean, not a half-cycle step
            fits[FaultType.BIAS] = TypeFit(sse_step, mean, ramp.b)
            return result(FaultType.OSCILLATION, amp, frequency_hz=freq)
        if kpk < params.osc_min_cycles:
            path.margins.append(1.0)  # fewer cycles than an oscillation shows: not one
        else:
            path.failed(*conds)

    ramp_sse = max(ramp.sse, 1e-300)
    step_sse = max(sse_step, 1e-300)
    step_conds = ((ramp_sse, step_sse, sse_step < ramp.sse), (step_height, a_min,
                                                               step_height > a_min))
    if step_wins:
        path.passed(*((x, th) for x, th, _ in step_conds))
        return result(FaultType.BIAS, lvl1)
    path.failed(*step_conds)

    change = abs(ramp.change)
    if change > a_min:
        path.passed((change, a_min))
        rate = abs(ramp.b)
        path.passed((rate, params.runaway_rate_per_s))
        kind = FaultType.RUNAWAY if rate >= params.runaway_rate_per_s else FaultType.DRIFT
        return result(kind, ramp.end)
    path.failed((change, a_min, False))

    if abs(mean) > a_min:
        path.passed((abs(mean), a_min))
        return result(FaultType.BIAS, mean)
    path.failed((abs(mean), a_min, False))

    noise_th = params.noise_std_ratio * sigma
    if std > noise_th:
        path.passed((std, noise_th))
        return result(FaultType.NOISE, excess)
    return result(FaultType.UNKNOWN, mean)


@dataclass(frozen=True, slots=True)
class Label:
    """What an alarm says about its fault: the held type, its magnitude on the latest window
    (from that type's own model), and the confidence in the type."""

    fault_type: FaultType
    magnitude: float
    confidence: float
    rate_per_s: float = math.nan
    frequency_hz: float = math.nan

    def message(self) -> str:
        msg = f"{self.fault_type.value} {self.magnitude:.4g}"
        if self.fault_type is FaultType.OSCILLATION and math.isfinite(self.frequency_hz):
            msg += f" at {self.frequency_hz:.3g} Hz"
        elif self.fault_type in (FaultType.DRIFT, FaultType.RUNAWAY):
            msg += f" rate {self.rate_per_s:.4g}/s"
        return msg


_RAMPS = frozenset({FaultType.DRIFT, FaultType.RUNAWAY})


def relabel_wins_n(relabel_windows: float, history_n: int, reclassify_every_n: int) -> int:
    """Consecutive re-classifications, every ``reclassify_every_n`` samples of a window of
    ``history_n``, that span ``relabel_windows`` windows of new data (at least 2)."""
    span = math.ceil(relabel_windows * history_n / max(reclassify_every_n, 1) - 1e-9)
    return max(2, 1 + span)


class LabelHysteresis:
    """The fault type of one alarm: decided at the raise, changed only on decisive evidence
    (module doc, "The label of an alarm").

    :meth:`decide` at the raise, :meth:`update` at each re-classification while the alarm is
    active; both return the :class:`Label` to report.

    Parameters
    ----------
    params : the channel's classifier parameters
    wins_n : consecutive decisive wins a new type needs (:func:`relabel_wins_n`)
    """

    __slots__ = ("p", "wins_n", "held", "_confidence", "_rival", "_wins")

    def __init__(self, params: ClassifierParams, wins_n: int) -> None:
        if wins_n < 1:
            raise ValueError(f"wins_n must be >= 1, got {wins_n}")
        self.p = params
        self.wins_n = wins_n
        self.held = FaultType.UNKNOWN
        self._confidence = 0.0
        self._rival: FaultType | None = None
        self._wins = 0

    def decide(self, c: Classification) -> Label:
        """The raise: the window's type is the alarm's type."""
        self.held = c.fault_type
        self._confidence = c.confidence
        self._rival, self._wins = None, 0
        return self._label(c)

    def update(self, c: Classification) -> Label:
        """A re-classification of the active alarm."""
        new = c.fault_type
        if (new is self.held or self.held is FaultType.UNKNOWN or new in OBSERVED_TYPES
                or self.held in OBSERVED_TYPES):
            return self.decide(c) if new is not FaultType.UNKNOWN else self._label(c)
        if new is FaultType.UNKNOWN or not self._decisive(c):
            self._rival, self._wins = None, 0
            return self._label(c)
        if new is self._rival:
            self._wins += 1
        else:
            self._rival, self._wins = new, 1
        if self._wins >= self.wins_n:
            return self.decide(c)
        return self._label(c)

    def _decisive(self, c: Classification) -> bool:
        held, new = self.held, c.fault_type
        if held in _RAMPS and new in _RAMPS:
            # the rate says which, if the window shows a ramp at all: a runaway at its limit
            # leaves a level, whose fitted "rate" is no evidence of a drift
            ramp, level = c.fits[new], c.fits[FaultType.BIAS]
            if not level.sse >= self.p.relabel_fit_ratio * ramp.sse:
                return False
            rate = abs(ramp.rate_per_s)
            ratio = self.p.relabel_rate_ratio
            if new is FaultType.RUNAWAY:
                return rate >= self.p.runaway_rate_per_s * ratio
            return rate <= self.p.runaway_rate_per_s / ratio
        old_fit, new_fit = c.fits.get(held), c.fits.get(new)
        if old_fit is None or new_fit is None or not (
                math.isfinite(old_fit.sse) and math.isfinite(new_fit.sse)):
            return True  # a type judged by a statistic (stuck, noise): its own test decided
        return old_fit.sse >= self.p.relabel_fit_ratio * new_fit.sse

    def _label(self, c: Classification) -> Label:
        held = self.held
        conf = self._confidence * (1.0 - self._wins / self.wins_n)
        if held is c.fault_type:
            return Label(held, c.magnitude, conf, c.rate_per_s, c.frequency_hz)
        fit = c.fits.get(held)
        if fit is None:
            return Label(held, math.nan, conf)
        return Label(held, fit.magnitude, conf, fit.rate_per_s, fit.frequency_hz)
