"""Time base of a log's GNSS velocity against its IMU, measured from the log itself.

A GNSS receiver's velocity is the velocity of an instant before the autopilot logs it: the
receiver computes its solution (tens of ms), sends it over a serial link, and the autopilot
stamps the record when it arrives. An autopilot's own estimator allows for this delay (ArduPilot
``GPS_DELAY_MS``, PX4 ``EKF2_GPS_DELAY``, typically 100-220 ms). A log records the arrival time. A
monitor that compares the integrated IMU with that velocity at the logged time sees, in every
acceleration, a mismatch of ``lag x a``. Lu2016's GS-KM takes that mismatch for an IMU fault.
Measured on the real data (shared/data/real/README.md):

* erle_copter_16.BIN and erle_copter_loiter_rtl.bin (ArduCopter on an Erle PXF, u-blox): the
  integrated IMU explains the GPS velocity increments best 0.20 s before the GPS record's time
  (1 s increments, bias removed, trimmed RMS 0.131 m/s against 0.142 m/s at 0 s and 0.157 m/s
  at 0.5 s; the copters mostly hover, so the curve is shallow but has one minimum);
* onspeed_vac_decel_stall_50hz.csv (VN-300 raw GNSS velocity): 0.10-0.20 s (D 0.14 m/s at
  0.2 s against 0.29 m/s at 0 s), while the VN-300's own INS velocity fits best at 0 s.

:func:`gnss_velocity_lag_s` measures that lag: the IMU specific force, rotated into NED by the
logged attitude, plus gravity, is integrated. Its increments over about 1 s are compared with
the GNSS velocity's increments at trial lags. A constant per axis per increment (an
accelerometer bias, a gravity error) is removed by least squares. The lag with the smallest
trimmed residual wins. The readers of raw receiver velocity (DataFlash ``GPS``, the OnSpeed
VN-300 GNSS columns, PX4 ``vehicle_gps_position``) shift the GNSS time stamps back by it and
say so in the log's notes. Velocities that are an estimator's output (Zipline, ALFA, PX4
``vehicle_local_position``) already fit at lag 0 and are not shifted.

:func:`clock_rate` measures the log's boot clock against GPS time (the receiver's time of week
advances at the true rate). A crystal is within 1e-4. A boot clock that runs 8 % slow (the
Linux-based Erle PXF autopilot of erle_copter_loiter_rtl.bin: 232 s of boot time for 253 s
of GPS time) stretches every IMU interval. The integrated IMU then falls 8 % short of the GPS
velocity change: the vertical gain of the IMU-integrated increments against the GPS increments
is 1.09 on the boot clock, 1.00 on the corrected one.

Pure functions over numpy arrays (no file access): the readers call them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gcs_monitor.core.constants import GRAVITY_STD_MPS2
from gcs_monitor.core.types import Mat, Vec

LAG_MAX_S = 0.5  # longest receiver latency searched (typical 0.1-0.22 s; 2.5 x the longest)
LAG_STEP_S = 0.01
INCREMENT_S = 1.0  # span of the compared velocity increments
TRIM = 0.1  # share of the largest residuals left out (crashes, hard landings, glitches)
# a lag is taken only when its residual is this much below the residual at 0 and at the end of
# the search (a minimum, not a slope; a vehicle that hardly accelerates leaves the curve flat)
MIN_GAIN = 0.03
MIN_INCREMENTS = 20  # windows needed at all
MAX_IMU_GAP_S = 0.5  # IMU gaps beyond this break the integration: no window spans one
CLOCK_RATE_TOL = 0.01  # |rate - 1| beyond this is no crystal's drift: a wrong clock


@dataclass(frozen=True, slots=True)
class LagEstimate:
    """The measured GNSS velocity lag behind the IMU.

    Attributes
    ----------
    lag_s : lag (s) >= 0: the GNSS velocity stamped t is the velocity at t - lag_s; 0 when
        not determined
    determined : the residual at ``lag_s`` is at least ``MIN_GAIN`` below the ones at 0 and at
        ``LAG_MAX_S``
    rms_at_lag_mps, rms_at_zero_mps : trimmed RMS of the increment residual (m/s) at the
        lag and at 0 (NaN when not enough data)
    n_windows : increments compared
    """

    lag_s: float
    determined: bool
    rms_at_lag_mps: float
    rms_at_zero_mps: float
    n_windows: int

    def note(self, what: str) -> str:
        """One line for a log's notes."""
        if not self.determined:
            return (f"{what}: lag behind the IMU not determined from the log "
                    f"({self.n_windows} increments); time stamps kept")
        return (f"{what}: lag behind the IMU measured {self.lag_s:.2f} s (increment residual "
                f"{self.rms_at_lag_mps:.3f} m/s against {self.rms_at_zero_mps:.3f} m/s at 0 s); "
                f"time stamps moved back by it")


def _dcm_rows(euler_rad: Mat) -> tuple[Vec, ...]:
    """The nine elements of C_ned_frd (ZYX Euler, as core.frames.dcm_ned_frd), per row of
    ``euler_rad`` (n, 3)."""
    ph, th, ps = euler_rad[:, 0], euler_rad[:, 1], euler_rad[:, 2]
    sph, cph, sth, cth, sps, cps = (np.sin(ph), np.cos(ph), np.sin(th), np.cos(th), np.sin(ps),
                                    np.cos(ps))
    return (cth * cps, sph * sth * cps - cph * sps, cph * sth * cps + sph * sps,
            cth * sps, sph * sth * sps + cph * cps, cph * sth * sps - sph * cps,
            -sth, sph * cth, cph * cth)


def integrated_velocity(t_s: Vec, acc_frd_mps2: Mat, euler_rad: Mat, *,
                        g_mps2: float = GRAVITY_STD_MPS2) -> tuple[Vec, Mat]:
    """Velocity change integrated from the IMU (trapezoid), NED, from the first sample.

    ``a_ned = C_ned_frd(euler) f + [0, 0, g]`` (the GS-KM's velocity equation, Lu2016 eq. 11,
    without the earth-rate terms, which are below 1e-3 m/s^2). Across an IMU gap longer than
    ``MAX_IMU_GAP_S`` nothing is integrated. Returns ``(segment id per sample, (n, 3) velocity)``:
    increments are meaningful only within one segment.
    """
    c = _dcm_rows(euler_rad)
    f = acc_frd_mps2
    a = np.column_stack([c[0] * f[:, 0] + c[1] * f[:, 1] + c[2] * f[:, 2],
                         c[3] * f[:, 0] + c[4] * f[:, 1] + c[5] * f[:, 2],
                         c[6] * f[:, 0] + c[7] * f[:, 1] + c[8] * f[:, 2] + g_mps2])
    dt = np.diff(t_s)
    gap = (dt > MAX_IMU_GAP_S) | (dt <= 0.0)
    step = 0.5 * (a[1:] + a[:-1]) * np.where(gap, 0.0, dt)[:, None]
    v = np.vstack([np.zeros(3), np.cumsum(step, axis=0)])
    seg = np.concatenate([[0], np.cumsum(gap)])
    return seg.astype(np.float64), v


def gnss_velocity_lag_s(t_imu_s: Vec, acc_frd_mps2: Mat, euler_rad: Mat, t_vel_s: Vec,
                        vel_ned_mps: Mat) -> LagEstimate:
    """How far the GNSS velocity lags the IMU (module docstring).

    Parameters
    ----------
    t_imu_s : (n,) IMU sample times (s), increasing
    acc_frd_mps2 : (n, 3) specific force, body FRD
    euler_rad : (n, 3) roll, pitch, yaw at the IMU times (yaw unwrapped)
    t_vel_s : (m,) GNSS velocity time stamps (s), increasing, on the IMU's clock
    vel_ned_mps : (m, 3) GNSS velocity, NED
    """
    seg, v_imu = integrated_velocity(t_imu_s, acc_frd_mps2, euler_rad)
    lags = np.arange(0.0, LAG_MAX_S + 0.5 * LAG_STEP_S, LAG_STEP_S)
    if len(t_vel_s) < 3 or len(t_imu_s) < 3:
        return LagEstimate(0.0, False, math.nan, math.nan, 0)
    per = float(np.median(np.diff(t_vel_s)))
    k = max(1, int(round(INCREMENT_S / per))) if per > 0 else 1
    i0, i1 = np.arange(len(t_vel_s) - k), np.arange(k, len(t_vel_s))
    ta, tb = t_vel_s[i0], t_vel_s[i1]
    # windows inside the IMU span at every trial lag, on one IMU segment, not across a GNSS gap
    ok = (ta - LAG_MAX_S > t_imu_s[0]) & (tb < t_imu_s[-1]) & (tb - ta < 2.0 * k * per)
    seg_a = np.interp(ta - LAG_MAX_S, t_imu_s, seg)
    seg_b = np.interp(tb, t_imu_s, seg)
    ok &= seg_a == seg_b
    i0, i1, ta, tb = i0[ok], i1[ok], ta[ok], tb[ok]
    n = len(i0)
    if n < MIN_INCREMENTS:
        return LagEstimate(0.0, False, math.nan, math.nan, n)
    dg = vel_ned_mps[i1] - vel_ned_mps[i0]
    span = tb - ta
    cost = np.empty(len(lags))
    for j, lag in enumerate(lags):
        di = np.column_stack([np.interp(tb - lag, t_imu_s, v_imu[:, a])
                              - np.interp(ta - lag, t_imu_s, v_imu[:, a]) for a in range(3)])
        r = dg - di
        # per axis, the bias b (r = b span) by least squares: an accelerometer bias or gravity
        b = (r * span[:, None]).sum(axis=0) / float(span @ span)
        e2 = ((r - span[:, None] * b) ** 2).sum(axis=1)
        keep = np.sort(e2)[: max(1, int(round((1.0 - TRIM) * n)))]
        cost[j] = math.sqrt(float(keep.mean()) / 3.0)
    best = int(np.argmin(cost))
    determined = bool(cost[best] < (1.0 - MIN_GAIN) * min(cost[0], cost[-1]))
    return LagEstimate(float(lags[best]) if determined else 0.0, determined,
                       float(cost[best]), float(cost[0]), n)


def clock_rate(t_boot_s: Vec, t_gnss_s: Vec) -> float:
    """Rate of the boot clock against GNSS time: the slope of boot time over GNSS time,
    fitted by least squares, refitted without residuals beyond 5 median absolute deviations
    (arrival jitter, a stray record). 1.0 for a sound clock; NaN with fewer than 10 samples or
    less than 10 s of GNSS time."""
    t_boot_s = np.asarray(t_boot_s, dtype=np.float64)
    t_gnss_s = np.asarray(t_gnss_s, dtype=np.float64)
    if len(t_boot_s) < 10 or float(np.ptp(t_gnss_s)) < 10.0:
        return math.nan
    x = t_gnss_s - t_gnss_s[0]
    y = t_boot_s - t_boot_s[0]
    keep = np.ones(len(x), dtype=bool)
    slope = math.nan
    for _ in range(3):
        slope, icpt = np.polyfit(x[keep], y[keep], 1)
        r = y - (slope * x + icpt)
        mad = float(np.median(np.abs(r[keep] - np.median(r[keep]))))
        new = np.abs(r - np.median(r[keep])) <= max(5.0 * 1.4826 * mad, 1e-3)
        if np.array_equal(new, keep) or new.sum() < 10:
            break
        keep = new
    return float(slope)


def clock_wrong(rate: float) -> bool:
    """The boot clock is off by more than any crystal (``CLOCK_RATE_TOL``)."""
    return math.isfinite(rate) and abs(rate - 1.0) > CLOCK_RATE_TOL
