"""First fault classification from the residual's shape over a window.

Fault families follow Wan2018 Table II and the project's fault profiles: bias (step, then
flat), drift (slow linear trend), runaway (fast monotonic ramp), oscillation (periodic),
stuck/jamming (the measurement stops moving), noise (variance increase, zero mean).

Decision rule, in this order (each test is a documented, tunable parameter in
:class:`ClassifierParams`; ``a_min = min_fault_sigma * noise_sigma`` is the smallest fault
worth naming):

1. stuck: the *measurement* (when given) has std < ``stuck_std_ratio * noise_sigma``,
   i.e. less than a healthy sensor's own noise.  Magnitude: mean residual.
2. oscillation: after removing a linear trend, the strongest FFT bin carries more than
   ``osc_power_fraction`` of the variance, the window holds at least ``osc_min_cycles``
   periods and the amplitude ``sqrt(2) * std`` exceeds ``a_min``.  Magnitude: amplitude.
3. step-then-flat vs ramp: the best two-level (one change point) fit and the least-squares
   line are compared by their sums of squared errors.  If the step fits better and the
   step exceeds ``a_min``: bias, magnitude = level after the step.
4. ramp: slope * window length exceeds ``a_min``: runaway if ``|slope| >= runaway_rate``,
   else drift.  Magnitude: fitted fault value at the last sample; ``rate_per_s`` the slope.
5. flat offset: ``|mean| > a_min``: bias (onset before the window), magnitude = mean.
6. noise: std > ``noise_std_ratio * noise_sigma`` with zero mean: magnitude = excess
   std ``sqrt(std^2 - noise_sigma^2)``.
7. otherwise unknown.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from gcs_monitor.core.params import param
from gcs_monitor.fdi.events import FaultType


@dataclass(frozen=True, slots=True)
class ClassifierShape:
    """The shape tests of the classifier, common to every channel (project choices, see the
    module doc); ``[classifier]`` in the configuration."""

    min_fault_sigma: float = param(4.0, "smallest fault worth naming, in noise sigmas (a_min)",
                                   positive=True)
    stuck_std_ratio: float = param(0.2, "a measurement whose std is below this fraction of "
                                   "the noise sigma is stuck", positive=True)
    osc_power_fraction: float = param(0.5, "share of the detrended variance the strongest "
                                      "frequency must carry for an oscillation",
                                      positive=True)
    osc_min_cycles: float = param(2.0, "periods an oscillation must show in the window (a step "
                                  "leaves a one-cycle sawtooth after detrending)", positive=True)
    noise_std_ratio: float = param(2.0, "std above this many noise sigmas with zero mean is a "
                                   "noise fault", positive=True)


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

    def __post_init__(self) -> None:
        if not self.noise_sigma > 0.0:
            raise ValueError(f"noise_sigma must be > 0, got {self.noise_sigma}")
        if not self.runaway_rate_per_s > 0.0:
            raise ValueError(f"runaway_rate_per_s must be > 0, got {self.runaway_rate_per_s}")

    @classmethod
    def of(cls, noise_sigma: float, runaway_rate_per_s: float,
           shape: ClassifierShape = _SHAPE) -> ClassifierParams:
        """The parameters of one channel with the common shape tests."""
        return cls(noise_sigma, runaway_rate_per_s, shape.min_fault_sigma, shape.stuck_std_ratio,
                   shape.osc_power_fraction, shape.osc_min_cycles, shape.noise_std_ratio)


@dataclass(frozen=True, slots=True)
class Classification:
    """Result of :func:`classify_residual`.

    magnitude : signed fault value at the end of the window (bias, drift, runaway, stuck),
        oscillation amplitude, or excess noise std; SI
    rate_per_s : fitted slope, SI/s (drift/runaway; the fit slope otherwise)
    frequency_hz : dominant frequency (oscillation), else NaN
    """

    fault_type: FaultType
    magnitude: float
    rate_per_s: float = math.nan
    frequency_hz: float = math.nan


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
    span_s = t[-1]

    slope, icpt = np.polyfit(t, r, 1)
    lin_fit = icpt + slope * t
    e_lin = r - lin_fit
    sse_lin = float(e_lin @ e_lin)

    if measured is not None:
        m = np.asarray(measured, dtype=np.float64)
        if m.size >= 4 and float(np.std(m)) < params.stuck_std_ratio * sigma:
            return Classification(FaultType.STUCK, float(np.mean(r[-max(4, n // 4) :])),
                                  rate_per_s=float(slope))

    # oscillation: dominant spectral line of the detrended residual
    var_lin = sse_lin / n
    spec = np.abs(np.fft.rfft(e_lin)) ** 2
    spec[0] = 0.0
    if spec.size > 2 and var_lin > 0.0:
        kpk = int(np.argmax(spec))
        # Parseval: a bin k (0 < k < N/2) holds 2|X_k|^2 / N^2 of the variance
        frac = 2.0 * float(spec[kpk]) / (n * n) / var_lin
        # a line between bins leaks into the neighbour: count the two strongest adjacent bins
        if 0 < kpk < spec.size - 1:
            frac += 2.0 * float(max(spec[kpk - 1], spec[kpk + 1])) / (n * n) / var_lin
        amp = math.sqrt(2.0 * var_lin)
        if frac > params.osc_power_fraction and kpk >= params.osc_min_cycles and amp > a_min:
            return Classification(FaultType.OSCILLATION, amp, rate_per_s=float(slope),
                                  frequency_hz=kpk / (n * dt_s))

    sse_step, lvl0, lvl1, _ = _best_step(r)
    if sse_step < sse_lin and abs(lvl1 - lvl0) > a_min:
        return Classification(FaultType.BIAS, lvl1, rate_per_s=float(slope))

    if abs(slope) * span_s > a_min:
        kind = FaultType.RUNAWAY if abs(slope) >= params.runaway_rate_per_s else FaultType.DRIFT
        return Classification(kind, float(lin_fit[-1]), rate_per_s=float(slope))

    mean = float(np.mean(r))
    if abs(mean) > a_min:
        return Classification(FaultType.BIAS, mean, rate_per_s=float(slope))

    std = float(np.std(r))
    if std > params.noise_std_ratio * sigma:
        return Classification(FaultType.NOISE, math.sqrt(std * std - sigma * sigma),
                              rate_per_s=float(slope))
    return Classification(FaultType.UNKNOWN, mean, rate_per_s=float(slope))
