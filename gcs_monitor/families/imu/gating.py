"""Input validity and measurement step gating for the IMU fault estimators (Lu2016 GS-KM).

Two things on real flight data are not IMU faults but look like them to a filter whose only
fault model is "the IMU is wrong" (Lu2016 eqs. 5-8, faults added to the measured input):

1. **The input changes faster than the sample rate resolves.** The filter integrates the GS-KM
   (Lu2016 eq. 31) with the IMU linear between samples (Heun). If the specific force steps inside
   a sample interval (a catapult stroke: 0 -> 60 m/s^2 within one 20 ms sample), the true
   velocity increment lies anywhere between the zero-order-hold and the first-order-hold
   integrals; the difference is up to ``dt |Delta^2 u| / 2`` (for a step from a constant input
   the backward second difference ``Delta^2 u_k = u_k - 2 u_{k-1} + u_{k-2}`` equals the step;
   for an input smooth on the sample scale it is ``u'' dt^2``, negligible). That uncertainty is
   process noise, not a fault: :func:`intra_sample_input_var` adds it to the input noise Q of
   that one step (Lu2016 eq. 56), only for the part of ``|Delta^2 u|`` that the sensor noise
   cannot explain (white noise gives ``std(Delta^2 u) = sqrt(6) sigma``). The covariance
   matching of eq. 53 subtracts the same Q, so the adapted Q^f does not open either.

   **The sample's instant of validity** is a second, separate uncertainty (ours, measured on
   the Zipline launches). HIGHRES_IMU does not say whether a sample is the specific force at its
   time stamp or its mean over the interval before it. Real IMUs mostly deliver the mean
   (averaged or delta-velocity samples), and the simulator delivers the instant. The GS-KM
   integrates with the input linear between samples (first-order hold, right for the instant).
   For interval means, the zero-order hold on the newer sample is right. The two increments
   differ by ``dt |Delta u| / 2`` with the *first* difference ``Delta u_k = u_k - u_{k-1}``,
   i.e. a time shift of half a sample. On all 64 Zipline launches the navigation velocity fits
   the IMU integrated by the trapezoid 10 ms (half a sample) late: over the catapult stroke,
   RMS 0.36 m/s at 0 ms against 0.07 m/s at -10 ms. During a 60 m/s^2 stroke that shift is a
   0.6 m/s velocity mismatch, which the filter took for an accelerometer fault (acc x 0.4-0.5
   m/s^2 after the stroke). The same form of process noise covers it:
   ``max(0, |Delta u| - gate_sigma sqrt(2) sigma)`` (white noise: ``std(Delta u) =
   sqrt(2) sigma``), variance ``(excess / 2)^2``. Per channel, the larger of the two terms is
   taken. On inputs that change slowly on the sample scale, as the simulator's do, both are
   zero (:func:`intra_sample_excess_var`).

2. **The velocity or attitude reference jumps** (a GNSS/INS estimator reset, a GPS glitch). A
   step in one sample that the integrated IMU cannot explain is tested on the one-step
   increment, not on the innovation: for an accelerometer fault of size b the increment of the
   measured velocity differs from the IMU-predicted increment by ``b dt`` per sample, for a step
   of the reference by the step itself in one sample (the same for the Euler angles and a gyro
   fault). :class:`MeasurementStepGate` rejects a measurement group (velocity, or attitude)
   whose increment mismatch exceeds :func:`step_bound` (noise, intra-sample term and the
   largest fault step the fault model admits), and decides on the next sample: back to the
   state (a spike: accept), or a persistent offset with a consistent increment (a step:
   re-anchor those states on the measurement, keep the fault estimates). Lu2016 has no such
   gate (its sec. 5 flight data have no resets); a fault step beyond the admitted one is
   outside the fault model of Lu2016 sec. 3.1 (random walk with the prior of FaultPrior).

3. **The reference corrects itself over seconds** (ours, measured on the 64 Zipline launches).
   A velocity and position that are the outputs of the vehicle's own navigation filter are not
   kinematic measurements while that filter applies corrections. After the catapult, until its
   GNSS reset at 7.94 s, every Zipline flight's velocity departs from the integrated specific
   force: the mean body-z misfit ``dv/dt - (R f + g)`` over 0.5-2 s after launch is 0.07-0.54
   m/s^2 (median 0.27), against ~0.03 on the launcher. The GS-KM filter cannot tell that from an
   accelerometer bias: f_hat_Az reaches 0.2-0.55 m/s^2 whatever the noise model (the noise
   measured on the flights gives the same), above the simulator's J_th (0.19 m/s^2). The same
   reference's position then does not follow its own velocity: the largest
   ``|Delta p - integral v dt| / T`` down over 1 s windows is 0.67-3.8 m/s (median 1.4) in
   0.5-7.4 s after launch, 0.01-0.28 (median 0.02) on the launcher and median 0.07 after the
   reset. An IMU fault changes neither the reference position nor its velocity, so this test of
   the reference against itself cannot be opened by the faults the family reconstructs.
   :class:`ReferenceConsistency` measures it from the GPS samples against the position noise it
   measures itself (robust second differences: a raw GNSS position with metre noise makes it
   insensitive); what exceeds that bound, divided by the window (a velocity error of that size
   changing within it), is an acceleration error of the reference, and the accelerometer
   channels' J_th is raised by it while it lasts and ``reference_hold_s`` after
   (families/imu/family.py). Faults larger than the reference's own error are still detected;
   the channels are never switched off.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from gcs_monitor.core.constants import EARTH_RADIUS_M
from gcs_monitor.core.types import Vec

SQRT6 = math.sqrt(6.0)  # std of the second difference of unit white noise
SQRT2 = math.sqrt(2.0)  # std of the first difference of unit white noise


@dataclass(frozen=True, slots=True)
class GateConfig:
    """Settings of the input-validity term and the velocity step gate.

    Attributes
    ----------
    gate_sigma : gate in standard deviations for both tests
    acc_fault_step_max_mps2 : largest accelerometer fault step (per sample) the fault model is
        meant to reconstruct; a velocity increment mismatch beyond ``dt`` times this plus the
        noise gate is not an IMU fault. Default: 3 sigma of the fault prior of
        :class:`gcs_monitor.families.imu.imu_ts.FaultPrior` (5 m/s^2), i.e. 15 m/s^2.
    gyro_fault_step_max_radps : the same for the gyro and the Euler angles: 3 x 5 deg/s.
    max_rejected_n : after this many consecutive rejected samples the gate re-anchors anyway
        (a mismatch that persists in the increments is an acceleration error, not a step)
    enabled : False turns both mechanisms off (the plain Lu2016 filter)
    sample_timing : the sample-timing term of item 1: half a sample of |Delta u| as process
        noise, since a sample may be the instant or the interval mean (module docstring)
    """

    gate_sigma: float = 3.0
    acc_fault_step_max_mps2: float = 15.0
    gyro_fault_step_max_radps: float = 15.0 * math.pi / 180.0
    max_rejected_n: int = 25
    enabled: bool = True
    sample_timing: bool = True

    def __post_init__(self) -> None:
        if not self.gate_sigma > 0.0:
            raise ValueError(f"gate_sigma must be > 0, got {self.gate_sigma}")
        if self.acc_fault_step_max_mps2 < 0.0 or self.gyro_fault_step_max_radps < 0.0:
            raise ValueError("acc_fault_step_max_mps2 and gyro_fault_step_max_radps must be >= 0")
        if self.max_rejected_n < 1:
            raise ValueError("max_rejected_n must be >= 1")


def intra_sample_excess_var(u_km2: Sequence[float], u_km1: Sequence[float],
                            u_k: Sequence[float], floor: Sequence[float],
                            floor1: Sequence[float] = ()) -> list[float] | None:
    """:func:`intra_sample_input_var` on plain floats for the per-sample path; ``floor`` is
    ``gate_sigma sqrt(6) sigma`` per channel (second difference), ``floor1`` ``gate_sigma
    sqrt(2) sigma`` (first difference, the sample-timing term; empty: not applied). None when
    no channel exceeds its floors."""
    out = None
    for i, (a, b, c, f) in enumerate(zip(u_km2, u_km1, u_k, floor, strict=True)):
        excess = abs(c - 2.0 * b + a) - f
        if floor1:
            excess = max(excess, abs(c - b) - floor1[i])
        if excess > 0.0:
            if out is None:
                out = [0.0] * len(floor)
            out[i] = 0.25 * excess * excess
    return out


def intra_sample_input_var(u_km2: Vec, u_km1: Vec, u_k: Vec, sigma: Vec, gate_sigma: float,
                           *, timing: bool = True) -> Vec:
    """Extra input variance of one step from the unresolved intra-sample input profile.

    ``excess = max(0, |u_k - 2 u_{k-1} + u_{k-2}| - gate_sigma sqrt(6) sigma)`` per channel,
    with ``timing`` also ``|u_k - u_{k-1}| - gate_sigma sqrt(2) sigma`` (the sample's instant of
    validity), the larger of the two; variance ``(excess / 2)^2`` (the midpoint of the ZOH/FOH
    bracket, see module docstring).

    Parameters
    ----------
    u_km2, u_km1, u_k : (b,) measured inputs at k-2, k-1, k (SI)
    sigma : (b,) 1-sigma input noise (SI)
    gate_sigma : noise gate
    """
    floor = (gate_sigma * SQRT6 * np.asarray(sigma, dtype=np.float64)).tolist()
    floor1 = (gate_sigma * SQRT2 * np.asarray(sigma, dtype=np.float64)).tolist() if timing else []
    v = intra_sample_excess_var(np.asarray(u_km2).tolist(), np.asarray(u_km1).tolist(),
                                np.asarray(u_k).tolist(), floor, floor1)
    return np.zeros(len(floor)) if v is None else np.array(v)


def step_bound(s_diag: Sequence[float], extra_input_var: Sequence[float], dt_s: float,
               gate_sigma: float, fault_step_max: float, *,
               held_var: Sequence[float] = ()) -> float:
    """Largest one-step increment mismatch (norm) an IMU fault can explain.

    ``gate_sigma sqrt(2 tr S + dt^2 sum(extra_input_var)) + dt fault_step_max``: the increment
    mismatch is the difference of two innovations (variance <= 2 S each), plus the intra-sample
    input uncertainty of :func:`intra_sample_input_var` integrated over ``dt``, plus the
    largest admitted fault step times ``dt``. For the velocity group (m/s): accelerometer
    variances and ``acc_fault_step_max_mps2``; for the attitude group (rad): gyro variances
    and ``gyro_fault_step_max_radps`` (Euler rates ~ body rates for moderate pitch).

    Parameters
    ----------
    s_diag : (3,) innovation variances of the group's rows
    extra_input_var : (3,) extra input variance of this step (:func:`intra_sample_input_var`)
    dt_s : sample interval (s)
    held_var : (3,) extra variance of the previous measurement of the group when it was a held
        value (a measurement of an earlier instant; imu_ts: the attitude's ``(rate x age)^2``):
        the increment is taken from it
    """
    noise = (2.0 * math.fsum(s_diag) + dt_s * dt_s * math.fsum(extra_input_var)
             + math.fsum(held_var))
    return gate_sigma * math.sqrt(noise) + dt_s * fault_step_max


class GateDecision(StrEnum):
    ACCEPT = "accept"
    REJECT = "reject"  # velocity not used this sample (predict with the IMU only)
    REANCHOR = "reanchor"  # velocity states set to the measurement, fault estimates kept


class MeasurementStepGate:
    """Decision on each sample of one measurement group (module docstring, item 2).

    ``decide(nu, r_prev, bound)`` with ``nu`` the group's innovation of this sample (measured
    minus predicted), ``r_prev`` the previous sample's measured minus estimated value, so that
    ``nu - r_prev`` is the increment mismatch (measured increment minus IMU-predicted increment).
    """

    def __init__(self, cfg: GateConfig) -> None:
        self.cfg = cfg
        self.pending = False
        self.n_rejected = 0
        self.last_step = 0.0  # increment mismatch that opened the last rejection (norm)

    def reset(self) -> None:
        self.pending = False
        self.n_rejected = 0

    def decide(self, nu: Sequence[float], r_prev: Sequence[float], bound: float
               ) -> GateDecision:
        """``nu``, ``r_prev``: (3,) as in the class docstring (plain floats or arrays)."""
        inc = math.hypot(*[a - b for a, b in zip(nu, r_prev, strict=True)])
        if not self.pending:
            if inc <= bound:
                return GateDecision.ACCEPT
            self.pending = True
            self.n_rejected = 1
            self.last_step = inc
            return GateDecision.REJECT
        if math.hypot(*nu) <= bound:  # back on the state: it was a spike
            self.reset()
            return GateDecision.ACCEPT
        if inc <= bound or self.n_rejected >= self.cfg.max_rejected_n:
            self.reset()  # the offset persists with consistent increments: a step
            return GateDecision.REANCHOR
        self.n_rejected += 1
        return GateDecision.REJECT


MAD_SIGMA = 0.6745  # median absolute deviation of a unit Gaussian
# The GS-KM's spherical earth (R_e = 6367 km, Lu2016 eq. 11) against WGS-84's radii of curvature
# (meridian 6335-6400 km, prime vertical 6378-6400 km): a horizontal position from a receiver
# and a velocity integrated on the sphere differ by up to this share of the ground speed.
RADIUS_TOL = 0.0053
# GLOBAL_POSITION_INT carries lat/lon in 1e-7 deg (1.1 cm on the GS-KM's sphere): a position
# noise below its quantisation (sigma = LSB / sqrt 12) cannot be measured
POSITION_LSB_SIGMA_M = 1e-7 * math.pi / 180.0 * EARTH_RADIUS_M / math.sqrt(12.0)


class ReferenceConsistency:
    """The reference position against its own velocity (module docstring, item 3).

    ``add(q_us, vel_ned_mps, base)`` per Frame: ``q_us`` the instant the velocity is of (the
    Frame time minus the GPS delay), ``base`` ``(t_us, pos_ned_m)`` of a new GPS sample (None
    when the Frame brings none). The velocity is integrated by the trapezoid over the Frames;
    at each new GPS sample at least ``window_s`` (and ``min_periods`` of its own intervals)
    after an earlier one, ``c = (Delta p - integral v dt) / T`` is the inconsistency (m/s),
    horizontal (norm of north and east) and down apart. Bounds: ``gate_sigma sqrt(2 n)
    sigma_p / T`` (n = 2 horizontal, 1 down), ``sigma_p`` the position noise
    measured from the robust spread of the position's second differences (``MAD / 0.6745 /
    sqrt 6``, at least the quantisation of GLOBAL_POSITION_INT) over the last ``noise_n``
    samples; horizontally plus ``RADIUS_TOL`` times the
    ground speed. ``inconsistency_mps`` and ``bound_mps`` are those of the component further
    beyond (or nearer to) its bound. A component whose position has not changed at all over the
    window (a placeholder position, ALFA's converter writes one) is not tested.
    """

    def __init__(self, window_s: float, gate_sigma: float = 3.0, *, min_periods: float = 3.0,
                 noise_n: int = 50, max_gap_s: float = 0.5) -> None:
        if not (window_s > 0.0 and gate_sigma > 0.0 and noise_n >= 3):
            raise ValueError("ReferenceConsistency: window_s, gate_sigma > 0, noise_n >= 3")
        self.window_us = round(window_s * 1e6)
        self.gate_sigma = gate_sigma
        self.min_periods = min_periods
        self.max_gap_us = round(max_gap_s * 1e6)
        self._q_prev: int | None = None
        self._v_prev: tuple[float, float, float] = (0.0, 0.0, 0.0)
        self._integral = [0.0, 0.0, 0.0]  # integral of v since the chain started, m
        self._base: deque[tuple[int, tuple[float, ...], tuple[float, ...]]] = deque()
        self._d2: deque[float] = deque(maxlen=noise_n)  # second differences of position, m
        self.inconsistency_mps = math.nan  # the last one measured (norm)
        self.bound_mps = math.nan

    def reset(self) -> None:
        self._q_prev = None
        self._integral = [0.0, 0.0, 0.0]
        self._base.clear()
        self.inconsistency_mps = math.nan

    def sigma_pos_m(self) -> float:
        """Position noise measured from its second differences (NaN before 3 of them)."""
        if len(self._d2) < 3:
            return math.nan
        x = sorted(self._d2)
        med = x[len(x) // 2]
        mad = sorted(abs(v - med) for v in x)[len(x) // 2]
        return max(mad / MAD_SIGMA / math.sqrt(6.0), POSITION_LSB_SIGMA_M)

    def add(self, q_us: int, vel_ned_mps: Sequence[float] | Vec,
            base: tuple[int, Sequence[float]] | None) -> None:
        v = (float(vel_ned_mps[0]), float(vel_ned_mps[1]), float(vel_ned_mps[2]))
        if self._q_prev is not None and not 0 < q_us - self._q_prev <= self.max_gap_us:
            self.reset()  # a gap, or time going back: the integral starts again
        if self._q_prev is not None:
            h = 0.5e-6 * (q_us - self._q_prev)
            for i in range(3):
                self._integral[i] += h * (v[i] + self._v_prev[i])
        self._q_prev, self._v_prev = q_us, v
        if base is None:
            return
        t_b, p = base[0], tuple(float(x) for x in base[1])
        # the integral at the sample's own instant (a little before q_us: linear in between)
        back = 1e-6 * (q_us - t_b)
        i_b = tuple(self._integral[i] - back * v[i] for i in range(3))
        b = self._base
        if len(b) >= 2:  # second differences of the last three positions (noise)
            p0, p1 = b[-2][1], b[-1][1]
            for i in range(3):
                self._d2.append(p[i] - 2.0 * p1[i] + p0[i])
        b.append((t_b, p, i_b))
        span_min = self.window_us
        if len(b) >= 2:
            span_min = max(span_min, round(self.min_periods * (t_b - b[-2][0])))
        while len(b) > 2 and t_b - b[1][0] >= span_min:
            b.popleft()
        t_a, p_a, i_a = b[0]
        if t_b - t_a < span_min:
            return
        T = 1e-6 * (t_b - t_a)
        c = [((p[i] - p_a[i]) - (i_b[i] - i_a[i])) / T for i in range(3)]
        sp = self.sigma_pos_m()
        if not math.isfinite(sp):
            self.inconsistency_mps = self.bound_mps = math.nan
            return
        # horizontal and vertical apart: the horizontal position also carries the earth
        # model's scale (the GS-KM's sphere against the receiver's ellipsoid)
        v_h = math.hypot(i_b[0] - i_a[0], i_b[1] - i_a[1]) / T
        bounds = (self.gate_sigma * 2.0 * sp / T + RADIUS_TOL * v_h,
                  self.gate_sigma * SQRT2 * sp / T)
        mags = (math.hypot(c[0], c[1]), abs(c[2]))
        # a component that has not changed by a single bit over the window is no measured
        # position (a converter's placeholder, a held value): it is not tested
        excess = [mags[0] - bounds[0], mags[1] - bounds[1]]
        if p[0] == p_a[0] and p[1] == p_a[1]:
            excess[0] = -math.inf
        if p[2] == p_a[2]:
            excess[1] = -math.inf
        if excess[0] == excess[1] == -math.inf:
            self.inconsistency_mps = self.bound_mps = math.nan
            return
        k = 0 if excess[0] >= excess[1] else 1
        self.inconsistency_mps = mags[k]
        self.bound_mps = bounds[k]

    def consistent(self) -> bool | None:
        """True/False once measured, None before (too few samples)."""
        if not math.isfinite(self.inconsistency_mps) or not math.isfinite(self.bound_mps):
            return None
        return self.inconsistency_mps <= self.bound_mps
