"""Converted (SI, NED/FRD) samples of the slow inputs and the GPS velocity interpolation.

``ImuSample`` lives in ``frame.py`` (re-exported here). The interpolation is a pure function so
that its delay and no-look-ahead property can be tested on hand-made samples.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from gcs_monitor.core.types import Vec3
from gcs_monitor.telemetry.frame import ImuSample

__all__ = ["GpsSample", "GpsQuery", "ImuSample", "interpolate_gps"]


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
    """

    vel_ned_mps: Vec3 | None
    age_s: float
    base: GpsSample | None
    interpolated: bool


_NONE = GpsQuery(None, math.inf, None, False)


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
            return GpsQuery(v, age_us * 1e-6, g0, True)
    vel = g0.vel_ned_mps if age_us <= max_hold_us else None
    return GpsQuery(vel, age_us * 1e-6, g0, False)


def gps_sample(t_us: int, vn: float, ve: float, vd: float, lat_rad: float, lon_rad: float,
               alt_msl_m: float) -> GpsSample:
    """A GpsSample (its velocity array is shared between Frames: treat it as read-only)."""
    return GpsSample(t_us, np.array((vn, ve, vd)), lat_rad, lon_rad, alt_msl_m, (vn, ve, vd))
