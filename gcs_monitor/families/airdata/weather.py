"""The weather of the flight, estimated from what the vehicle sends (ours; Wan2018 leaves it to
the operator).

Wan2018 eq. 21b's wind bounds "need to be properly selected according to the weather and flight
conditions" (sec. VI-A); an operator does not know the turbulence before the flight. The wind is
measured kinematically at every air-data sample from signals the monitor already trusts:

    W_ned = V_gps_ned - C_ned_frd(phi, theta, psi) V_air_frd,
    V_air_frd = V_t [cos(alpha) cos(beta), sin(beta), sin(alpha) cos(beta)],

with V_t from the *fused* CAS (Wan2018 eq. 16 inverted, ISA), alpha the fused AoA (eq. 19) and
beta the sideslip vane (0 when absent). It is robust to the faults the family monitors: the
fused values leave isolated instances out, and the estimate is frozen while an instance is
suspected (its J above J_th, not yet isolated) and for ``hold_s`` after any isolation or
readmission, and while a set has no healthy instance. A relabel of an instance already
isolated (an UPDATED alarm event) does not hold it: that instance is out of the fusion already,
and holding on it froze the estimate for as long as any alarm stood.

*Thin sets.* A set with fewer than ``min_healthy`` (2) healthy instances is not used either: its
last instance cannot be judged by comparison, only against the CMHE's model, whose wind bounds
come from this estimate, so learning the weather from it turns its slow fault into wind and
widens the bounds that would catch it (Wan2018 campaign run 215: with aoa0 and aoa1 isolated,
aoa2's 0.77 deg/s runaway was learnt as a mean updraft growing to 68 m/s, the |W_z| bound
opened to 125 m/s, and the runaway to 33 deg was never alarmed). Holding the whole estimate
instead loses the wind the other set still measures (run 157: AoA thin from 97 s, then a 10
m/s shear that the healthy CAS triplex saw, never learnt; the CMHE's W_x ran into the old box
and all three CAS were flagged). So the thin set's quantity is taken from kinematics with the
learnt mean wind (:meth:`WeatherEstimator.kinematic_air`: alpha, or V_t, of
``V_ground - W_mean`` in body axes): the mean wind goes on following what the checked set and
the GPS say (the along-track wind from CAS when AoA is thin; the vertical from AoA when CAS is
thin), and the turbulence estimate holds, since part of each sample is the mean itself; such
samples do not count towards ``converge_s`` (run 151: CAS thin from 13.5 s, the turbulence
of the first seconds alone would have become the envelope at convergence and scheduled J_th
down onto the last CAS instance), so the prior stays in force until the estimate has
converged on checked samples. Both sets thin: no sample.

From the wind samples (one per air-data sample):

* the mean wind is a running mean over ``mean_window_s``; the envelope's steady wind is the
  largest horizontal (vertical) mean speed over the last ``memory_s``, which also holds a shear
  that moved the mean;
* the turbulence intensity is the RMS of the wind about that mean over ``turbulence_window_s``
  (the three axes averaged: Dryden's sigma_u = sigma_v = sigma_w at altitude), the largest of the
  last ``memory_s`` (fast attack, slow decay), times ``sigma_margin`` (a 30 s window holds about
  ten gust correlation times at transport speeds: the estimate's own spread is ~25 %);
* the shear rate is the largest change of the mean wind per second over ``memory_s``.

Until ``converge_s`` of usable samples have been seen, the declared weather (``[airdata.weather]``,
a prior) holds; afterwards the estimate does, never below ``floor``s that keep the CMHE's box open.
"""

from __future__ import annotations

import dataclasses
import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from gcs_monitor.core.atmosphere import tas_from_cas
from gcs_monitor.core.frames import dcm_ned_frd
from gcs_monitor.core.params import param
from gcs_monitor.models.airdata import WindEnvelope

US_PER_S = 1_000_000


@dataclass(frozen=True, slots=True)
class WeatherConfig:
    """Online estimate of the wind and the turbulence (``[airdata.estimate]``)."""

    enabled: bool = param(True, "estimate the weather from the flight (false: the declared "
                          "[airdata.weather] holds for the whole flight, as in Wan2018)")
    mean_window_s: float = param(20.0, "running mean of the wind", positive=True)
    turbulence_window_s: float = param(30.0, "span of the gust RMS", positive=True)
    memory_s: float = param(60.0, "the envelope holds the largest wind, turbulence and shear "
                            "rate of this span (fast attack, slow decay)", positive=True)
    converge_s: float = param(20.0, "usable wind samples needed before the estimate replaces "
                              "the declared prior", positive=True)
    hold_s: float = param(5.0, "no update for this long after an instance was isolated or "
                          "readmitted (not after a relabel of one already isolated)",
                          positive=True)
    min_healthy: int = param(2, "a set with fewer healthy instances (or fewer than all it "
                             "has) is not learnt from: its quantity comes from kinematics with "
                             "the learnt mean wind and the turbulence estimate holds (one "
                             "instance left has nothing to be checked against)", positive=True)
    sigma_margin: float = param(1.25, "turbulence estimate multiplied by this (its own spread "
                                "over one window)", positive=True)
    update_s: float = param(1.0, "the envelope is recomputed this often", positive=True)
    start_sigma_mps: float = param(3.54, "turbulence assumed until the estimate has converged, "
                                   "when the declared weather says less (Lu2016's Dryden "
                                   "default: the monitor starts conservative)", unit="kts")


@dataclass(frozen=True, slots=True)
class WeatherEstimate:
    """What the estimator says, SI: mean wind NED, gust RMS, the envelope in force."""

    converged: bool
    mean_wind_ned_mps: tuple[float, float, float]
    turbulence_sigma_mps: float
    envelope: WindEnvelope


def wind_ned(vel_ned_mps: np.ndarray, euler_rad: np.ndarray, cas_mps: float, aoa_rad: float,
             ssa_rad: float, alt_m: float) -> np.ndarray:
    """Kinematic wind ``W = V_ground - C_ned_frd V_air`` (module docstring), m/s NED."""
    return wind_ned_tas(vel_ned_mps, euler_rad, tas_from_cas(cas_mps, alt_m), aoa_rad, ssa_rad)


def wind_ned_tas(vel_ned_mps: np.ndarray, euler_rad: np.ndarray, tas: float, aoa_rad: float,
                 ssa_rad: float) -> np.ndarray:
    """:func:`wind_ned` with the true airspeed given."""
    ca, sa = math.cos(aoa_rad), math.sin(aoa_rad)
    cb, sb = math.cos(ssa_rad), math.sin(ssa_rad)
    v_air_frd = np.array([tas * ca * cb, tas * sb, tas * sa * cb], dtype=np.float64)
    C = dcm_ned_frd(float(euler_rad[0]), float(euler_rad[1]), float(euler_rad[2]))
    return np.asarray(vel_ned_mps, dtype=np.float64) - C @ v_air_frd


class _RunningMean:
    """Mean of a 3-vector over the last ``span_us`` of vehicle time (exact sums, O(1)).

    Python floats, each entry added, subtracted and divided as numpy's elementwise operations
    on the vector would (numpy's per-call overhead exceeds the arithmetic of three entries)."""

    __slots__ = ("span_us", "_buf", "_sum")

    def __init__(self, span_us: int) -> None:
        self.span_us = span_us
        self._buf: deque[tuple[int, tuple[float, float, float]]] = deque()
        self._sum = (0.0, 0.0, 0.0)

    def add(self, t_us: int, x: tuple[float, float, float]) -> tuple[float, float, float]:
        buf = self._buf
        buf.append((t_us, x))
        s0, s1, s2 = self._sum
        s0, s1, s2 = s0 + x[0], s1 + x[1], s2 + x[2]
        while buf[0][0] <= t_us - self.span_us:
            o = buf.popleft()[1]
            s0, s1, s2 = s0 - o[0], s1 - o[1], s2 - o[2]
        self._sum = (s0, s1, s2)
        n = len(buf)
        return s0 / n, s1 / n, s2 / n

    def __len__(self) -> int:
        return len(self._buf)


class _WindowMax:
    """Largest value of the last ``span_us`` (monotonic deque)."""

    __slots__ = ("span_us", "_q")

    def __init__(self, span_us: int) -> None:
        self.span_us = span_us
        self._q: deque[tuple[int, float]] = deque()

    def add(self, t_us: int, x: float) -> float:
        q = self._q
        while q and q[-1][1] <= x:
            q.pop()
        q.append((t_us, x))
        while q[0][0] <= t_us - self.span_us:
            q.popleft()
        return q[0][1]


class WeatherEstimator:
    """The flight's weather from its wind samples (see the module docstring)."""

    def __init__(self, cfg: WeatherConfig, prior: WindEnvelope) -> None:
        self.cfg = cfg
        self.prior = prior
        us = US_PER_S
        self._mean = _RunningMean(round(cfg.mean_window_s * us))
        self._gust2 = _RunningMean(round(cfg.turbulence_window_s * us))
        mem = round(cfg.memory_s * us)
        self._max_h = _WindowMax(mem)
        self._max_z = _WindowMax(mem)
        self._max_sigma = _WindowMax(mem)
        self._max_rate = _WindowMax(mem)
        self._usable_us = 0
        self._last_t: int | None = None
        self._last_mean: np.ndarray | None = None
        self._rate_ref: tuple[int, np.ndarray] | None = None
        self._hold_until = -(1 << 62)
        self._next_update = -(1 << 62)
        self._update_us = round(cfg.update_s * us)
        self._converge_us = round(cfg.converge_s * us)
        self._hold_us = round(cfg.hold_s * us)
        self._max_gap_us = round(cfg.update_s * us)
        self.estimate = WeatherEstimate(False, (math.nan,) * 3, math.nan, self._start_envelope())
        self._wind_h = self._wind_z = self._sigma = self._rate = 0.0

    def hold(self, t_us: int) -> None:
        """An instance was isolated (or its J crossed J_th): no update for ``hold_s``."""
        self._hold_until = max(self._hold_until, t_us + self._hold_us)

    def kinematic_air(self, vel_ned_mps: np.ndarray,
                      euler_rad: np.ndarray) -> tuple[float, float] | None:
        """(alpha rad, V_t m/s) that the ground velocity and the attitude give with the learnt
        mean wind, ``V_air = C_ned_frd^T (V_ground - W_mean)``: what stands in for a set that
        is down to its last healthy instance (module docstring, "thin sets"); None before any
        mean has been learnt."""
        m = self._last_mean
        if m is None:
            return None
        C = dcm_ned_frd(float(euler_rad[0]), float(euler_rad[1]), float(euler_rad[2]))
        vb = C.T @ (np.asarray(vel_ned_mps, dtype=np.float64) - m)
        return math.atan2(float(vb[2]), float(vb[0])), float(np.linalg.norm(vb))

    def add(self, t_us: int, wind: np.ndarray | None,
            gusts: bool = True) -> WindEnvelope | None:
        """One air-data sample's kinematic wind (None when it cannot be trusted); returns the
        new envelope when it is recomputed (every ``update_s``), else None. ``gusts`` False:
        the sample moves the mean wind only, the turbulence estimate holds (part of it came
        from kinematics, not from a sensor: "thin sets"), and it does not count towards
        ``converge_s``: an estimate that has not converged on checked samples keeps the prior."""
        w = (0.0, 0.0, 0.0) if wind is None else wind.tolist()
        if (wind is not None and t_us >= self._hold_until and math.isfinite(w[0])
                and math.isfinite(w[1]) and math.isfinite(w[2])):
            if (gusts and self._last_t is not None
                    and 0 < t_us - self._last_t <= self._max_gap_us):
                self._usable_us += t_us - self._last_t  # mean-only samples do not converge it
            self._last_t = t_us
            mean = self._mean.add(t_us, (w[0], w[1], w[2]))
            if gusts:
                g0, g1, g2 = w[0] - mean[0], w[1] - mean[1], w[2] - mean[2]
                v0, v1, v2 = self._gust2.add(t_us, (g0 * g0, g1 * g1, g2 * g2))
                var = (v0 + v1 + v2) / 3  # np.mean of three: ((v0 + v1) + v2) / 3
                self._sigma = self._max_sigma.add(t_us, math.sqrt(max(var, 0.0)))
            self._wind_h = self._max_h.add(t_us, math.hypot(mean[0], mean[1]))
            self._wind_z = self._max_z.add(t_us, abs(mean[2]))
            self._last_mean = np.array(mean)
        if t_us < self._next_update:
            return None
        self._next_update = t_us + self._update_us
        self._shear_rate(t_us)
        env = self._envelope()
        m = self._last_mean
        mean_ned = (float(m[0]), float(m[1]), float(m[2])) if m is not None \
            else (math.nan,) * 3
        self.estimate = WeatherEstimate(self._usable_us >= self._converge_us, mean_ned,
                                        self._sigma, env)
        return env

    def _shear_rate(self, t_us: int) -> None:
        """The change of the mean wind since the previous update, once the mean's window is
        full (its filling is not a shear); the memory max of it."""
        m = self._last_mean
        if m is None or self._usable_us < self._mean.span_us:
            return
        if self._rate_ref is not None:
            t0, m0 = self._rate_ref
            if t_us > t0:
                rate = float(np.linalg.norm(m - m0)) / ((t_us - t0) / US_PER_S)
                self._rate = self._max_rate.add(t_us, rate)
        self._rate_ref = (t_us, m.copy())

    def _start_envelope(self) -> WindEnvelope:
        """The declared prior, with at least ``start_sigma_mps`` of turbulence."""
        p = self.prior
        return dataclasses.replace(
            p, turbulence_sigma_mps=max(p.turbulence_sigma_mps, self.cfg.start_sigma_mps))

    def _envelope(self) -> WindEnvelope:
        if self._usable_us < self._converge_us:
            return self._start_envelope()
        return dataclasses.replace(
            self.prior, wind_mps=self._wind_h, wind_z_mps=self._wind_z, shear_mps=0.0,
            shear_z_mps=0.0, shear_rate_mps2=self._rate,
            turbulence_sigma_mps=self.cfg.sigma_margin * self._sigma)
