"""Converted (SI, NED/FRD) samples of the slow inputs and the GPS velocity interpolation.

``ImuSample`` lives in ``frame.py`` (re-exported here). The interpolation is a pure function so
that its delay and no-look-ahead property can be tested on hand-made samples.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from gcs_monitor.core.types import Vec3
from gcs_monitor.telemetry.frame import ImuSample, slot_setters

__all__ = ["GpsSample", "GpsQuery", "ImuChord", "ImuSample", "imu_chord", "interpolate_gps"]


@dataclass(frozen=True, slots=True)
class GpsSample:
    """One GLOBAL_POSITION_INT in SI: vehicle time, NED ground velocity, WGS-84 position."""

    t_us: int
    vel_ned_mps: Vec3
    lat_rad: float
    lon_rad: float
    alt_msl_m: float
    vel_tuple: tuple[float, float, float] = (math.nan, math.nan, math.nan)  # same, as floats


@dataclass(frozen=True, slots=True)
class GpsQuery:
    """Result of :func:`interpolate_gps` at one instant ``t_us``.

    vel_ned_mps : interpolated (or held) velocity, None when there is none valid
    age_s : ``t_us`` minus the time of the newest sample at or before ``t_us`` (inf if none)
    base : that newest sample at or before ``t_us`` (position and "new GPS" bookkeeping)
    interpolated : True when two samples bracket ``t_us``
    upper : the later sample of the bracketing pair (None unless interpolated)
    """

    vel_ned_mps: Vec3 | None
    age_s: float
    base: GpsSample | None
    interpolated: bool
    upper: GpsSample | None = None


_NONE = GpsQuery(None, math.inf, None, False)
_new = object.__new__
_QUERY_SET = slot_setters(GpsQuery)


def _query(vel: Vec3 | None, age_s: float, base: GpsSample | None, interpolated: bool,
           upper: GpsSample | None) -> GpsQuery:
    """``GpsQuery(vel, age_s, base, interpolated, upper)`` at less than half the cost (one per
    Frame), through :func:`~gcs_monitor.telemetry.frame.slot_setters`. The object is the
    same."""
    q = _new(GpsQuery)
    sv, sa, sb, si, su = _QUERY_SET
    sv(q, vel)
    sa(q, age_s)
    sb(q, base)
    si(q, interpolated)
    su(q, upper)
    return q


def interpolate_gps(ring: Sequence[GpsSample], t_us: int, max_gap_us: int,
                    max_hold_us: int) -> GpsQuery:
    """Linear interpolation of GPS ground velocity at ``t_us`` between the samples bracketing it.

    Lu2016 sec. 5 interpolates 1 Hz GPS to the 100 Hz IMU rate. Only samples at or before the
    newest one in ``ring`` are used, so the result never depends on data that has not arrived:
    the caller asks for ``t_us`` = (newest vehicle time) - D with D >= one GPS period so that a
    bracketing pair normally exists. Past the newest sample the newest velocity is held (never
    extrapolated) for at most ``max_hold_us``; bracketing samples further apart than
    ``max_gap_us`` (a GPS outage) are not interpolated across.

    Parameters
    ----------
    ring : GPS samples in increasing time order
    t_us : query instant (vehicle time, µs)
    """
    n = len(ring)
    if n == 0 or t_us < ring[0].t_us:
        return _NONE
    k = n - 1
    while ring[k].t_us > t_us:  # newest sample at or before t_us (k >= 0 by the check above)
        k -= 1
    g0 = ring[k]
    age_us = t_us - g0.t_us
    if k + 1 < n:
        g1 = ring[k + 1]
        span = g1.t_us - g0.t_us
        if span <= max_gap_us:
            w = age_us / span
            a, b = g0.vel_tuple, g1.vel_tuple  # float arithmetic: cheaper than 3-vector numpy
            v = np.array((a[0] + w * (b[0] - a[0]), a[1] + w * (b[1] - a[1]),
                          a[2] + w * (b[2] - a[2])))
            return _query(v, age_us * 1e-6, g0, True, g1)
    vel = g0.vel_ned_mps if age_us <= max_hold_us else None
    return _query(vel, age_us * 1e-6, g0, False, None)


def gps_sample(t_us: int, vn: float, ve: float, vd: float, lat_rad: float, lon_rad: float,
               alt_msl_m: float) -> GpsSample:
    """A GpsSample (its velocity array is shared between Frames: treat it as read-only)."""
    return GpsSample(t_us, np.array((vn, ve, vd)), lat_rad, lon_rad, alt_msl_m, (vn, ve, vd))


@dataclass(frozen=True, slots=True)
class ImuChord:
    """The IMU's velocity path across one GPS interval ``[t0_us, t1_us]``, measured against its
    chord (see :func:`imu_chord`).

    t_us : sample instants (µs), increasing, covering the interval
    dv : (n, 3) velocity change since ``t0_us`` at those instants, NED m/s (integrated IMU)
    """

    t0_us: int
    t1_us: int
    t_us: tuple[int, ...]
    dv: tuple[tuple[float, float, float], ...]
    mean_acc: tuple[float, float, float]  # NED m/s^2, mean over the interval

    def error_at(self, t_us: int) -> Vec3:
        """``e(tau) = tau a_mean - integral_0^tau a ds``: the linear interpolation between the
        interval's end samples minus the velocity the IMU integrates to at ``t_us``, NED m/s
        (Python floats: called at every frame)."""
        ts = self.t_us
        k = bisect.bisect_right(ts, t_us) - 1
        k = min(max(k, 0), len(ts) - 2)
        w = (t_us - ts[k]) / (ts[k + 1] - ts[k])
        p, q = self.dv[k], self.dv[k + 1]
        tau = (t_us - self.t0_us) * 1e-6
        a = self.mean_acc
        return np.array((tau * a[0] - (p[0] + w * (q[0] - p[0])),
                         tau * a[1] - (p[1] + w * (q[1] - p[1])),
                         tau * a[2] - (p[2] + w * (q[2] - p[2]))))


def imu_chord(t_us: Sequence[int], acc_ned_mps2: np.ndarray, t0_us: int,
              t1_us: int) -> ImuChord | None:
    """The deviation of the IMU-integrated velocity from its chord over a GPS interval.

    Lu2016 sec. 5 interpolates the GPS velocity linearly between samples ``T`` apart (1 Hz to
    100 Hz); the interpolated value has the interval's *mean* acceleration as its derivative.
    Its error against the true velocity is ``e(tau) = tau a_mean - integral_0^tau a ds``
    (``v_interp = v_0 + tau a_mean``, ``v = v_0 + integral a``), zero at both samples; in a
    manoeuvre with a 1 Hz GPS it reaches 0.2 m/s (docs/results.md, rate sweep), twenty times
    the GPS noise. The IMU measures ``a``: integrated by the trapezoid over the interval (its
    NED acceleration, specific force rotated by the attitude; the constant gravity cancels in
    ``e``) it gives ``e``. A constant accelerometer bias cancels too (it is in ``a_mean`` and
    in the integral alike): ``e`` is the *shape* of the acceleration inside the interval, which
    a GPS this slow does not resolve, not its mean, which the GPS measures.

    Parameters
    ----------
    t_us : IMU sample instants (µs), increasing; the first at or before ``t0_us``, the last at
        or after ``t1_us``
    acc_ned_mps2 : (n, 3) NED acceleration (or specific force: a constant offset cancels)
    t0_us, t1_us : the GPS samples bracketing the interval

    Returns None when the samples do not cover the interval or are fewer than two.
    """
    n = len(t_us)
    if n < 2 or t_us[0] > t0_us or t_us[-1] < t1_us or t1_us <= t0_us:
        return None
    # Python floats, in the operation order of the numpy formulation it replaces (bit-identical
    # results, tests/gcs_monitor/telemetry/test_samples.py): a dozen samples per interval, for
    # which numpy's per-call overhead cost more than the arithmetic
    ts = [t * 1e-6 for t in t_us]
    acc = np.asarray(acc_ned_mps2, dtype=np.float64).tolist()
    # trapezoid steps, cumulated in order (np.cumsum): cum[0] = 0, cum[1] = the first step
    cum: list[tuple[float, float, float]] = [(0.0, 0.0, 0.0)]
    cx = cy = cz = 0.0
    for k in range(n - 1):
        a0, a1 = acc[k], acc[k + 1]
        dt = ts[k + 1] - ts[k]
        sx = 0.5 * (a1[0] + a0[0]) * dt
        sy = 0.5 * (a1[1] + a0[1]) * dt
        sz = 0.5 * (a1[2] + a0[2]) * dt
        if k:
            cx, cy, cz = cx + sx, cy + sy, cz + sz
        else:
            cx, cy, cz = sx, sy, sz
        cum.append((cx, cy, cz))
    c0 = _interp(t0_us * 1e-6, ts, cum)
    c1 = _interp(t1_us * 1e-6, ts, cum)
    span_s = (t1_us - t0_us) * 1e-6
    mean = ((c1[0] - c0[0]) / span_s, (c1[1] - c0[1]) / span_s, (c1[2] - c0[2]) / span_s)
    dv = tuple((r[0] - c0[0], r[1] - c0[1], r[2] - c0[2]) for r in cum)
    return ImuChord(t0_us, t1_us, tuple(int(t) for t in t_us), dv, mean)


def _interp(x: float, xp: list[float], fp: list[tuple[float, float, float]]
            ) -> tuple[float, float, float]:
    """``np.interp(x, xp, fp[:, i])`` for the three columns of ``fp``, with numpy's own
    arithmetic and special cases (``xp`` increasing; the value at an exact sample point is that
    sample's; outside the range the end value), so the result is bit-identical."""
    n = len(xp)
    if x < xp[0]:
        return fp[0]
    j = bisect.bisect_right(xp, x) - 1
    if j >= n - 1 or xp[j] == x:
        return fp[j]
    x0, x1 = xp[j], xp[j + 1]
    f0, f1 = fp[j], fp[j + 1]
    out = []
    for i in range(3):
        slope = (f1[i] - f0[i]) / (x1 - x0)
        v = slope * (x - x0) + f0[i]
        if v != v:  # numpy: a NaN from one side, try the other
            v = slope * (x - x1) + f1[i]
            if v != v and f0[i] == f1[i]:
                v = f0[i]
        out.append(v)
    return (out[0], out[1], out[2])
