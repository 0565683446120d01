"""The Frame: one fixed-rate snapshot per IMU sample, in SI units and NED/FRD frames.

Slow inputs (air data, GPS, attitude) are held with their age; GPS ground velocity is linearly
interpolated to the IMU time with a bounded, documented delay (see ``assembler.py``).
A missing input is ``None`` or NaN with an explicit validity flag, never a silent zero.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from gcs_monitor.core.types import Vec, Vec3

GPS_AGE_PERIODS = 1.5  # an interpolated GPS velocity's base sample may be this many periods old


@dataclass(frozen=True, slots=True)
class ImuSample:
    """One IMU instance at one instant (HIGHRES_IMU)."""

    t_us: int
    instance: int
    acc_frd_mps2: Vec3  # (3,) specific force, body FRD
    omega_frd_radps: Vec3  # (3,) body rates, FRD


@dataclass(slots=True)
class Frame:
    """Everything the estimators see at one IMU sample of the primary IMU.

    Attributes
    ----------
    t_us : vehicle time of the primary IMU sample (int microseconds)
    imu : per IMU instance, the latest new sample (index = instance id); ``None`` where absent.
        A held (bit-identical repeated) sample is no new sample: the instance keeps the earlier
        one with its time, so ``imu[primary].t_us < t_us`` on the Frame of a held primary sample
    euler_rad : (3,) [phi, theta, psi] from ATTITUDE, or None
    gps_vel_ned_mps : (3,) GPS ground velocity, interpolated to ``t_us - gps_delay_us``, or None
    gps_delay_us : how far behind ``t_us`` the interpolated GPS velocity is (0 for held data)
    aoa_rad, cas_mps : (n,) per redundant instance; NaN where that instance has no valid data
    aoa_age_s, cas_age_s : (n,) age of each instance's latest value
    air_period_s : measured period of the air-data stream (s), NaN until two samples arrived
    output_delay_us : with ``align_delay_us`` set, every input of this frame is that much older
        than the newest data received (everything consistently delayed); 0 otherwise
    reset : the assembler was reset (autopilot reboot) just before this frame
    """

    t_us: int
    imu: list[ImuSample | None]
    euler_rad: Vec3 | None = None
    att_age_s: float = float("inf")
    gps_vel_ned_mps: Vec3 | None = None
    gps_age_s: float = float("inf")
    gps_delay_us: int = 0
    gps_new: bool = False  # a GPS sample arrived since the previous frame
    # the velocity is the newest GPS sample held past its time (no later sample brackets the
    # query instant), i.e. a measurement of t_us - gps_age_s, not of t_us
    gps_held: bool = False
    gps_period_s: float = float("nan")  # measured GPS period (median interval), s
    lat_rad: float = float("nan")
    lon_rad: float = float("nan")
    alt_msl_m: float = float("nan")
    aoa_rad: Vec = field(default_factory=lambda: np.full(3, np.nan))
    aoa_age_s: Vec = field(default_factory=lambda: np.full(3, np.inf))
    cas_mps: Vec = field(default_factory=lambda: np.full(3, np.nan))
    cas_age_s: Vec = field(default_factory=lambda: np.full(3, np.inf))
    air_new: bool = False  # new air data arrived since the previous frame
    # measured period of the air-data samples (median interval, s); NaN before two samples
    air_period_s: float = float("nan")
    ssa_rad: float = float("nan")
    baro_alt_m: float = float("nan")
    climb_mps: float = float("nan")  # positive up
    air_age_s: float = float("inf")
    static_pressure_pa: float = float("nan")
    oat_k: float = float("nan")
    surf_cmd_rad: Vec | None = None
    surf_pos_rad: Vec | None = None
    rod_pos_m: Vec | None = None
    surf_age_s: float = float("inf")
    # added by the assembler (telemetry room); see assembler.py for the delay conventions
    output_delay_us: int = 0  # how far behind the newest received vehicle time this frame is
    gps_fix: int = -1  # GPS_RAW_INT fix_type (-1: no GPS_RAW_INT seen); velocity needs >= 3
    reset: bool = False  # first frame after an assembler reset (autopilot reboot)
    # the IMU instance whose sample this frame is (it switches when the primary goes silent)
    primary: int = 0

    def gps_fresh(self, max_age_s: float) -> bool:
        """The GPS velocity is usable: held, no older than ``max_age_s``; interpolated, between
        samples no further apart than the stream's own period allows (a 1 Hz GPS's interpolated
        value is up to 1 s past its base sample and still current)."""
        if self.gps_vel_ned_mps is None:
            return False
        limit = max_age_s
        if not self.gps_held and self.gps_period_s == self.gps_period_s:
            limit = max(max_age_s, GPS_AGE_PERIODS * self.gps_period_s)
        return self.gps_age_s <= limit

    @property
    def primary_imu(self) -> ImuSample | None:
        """The latest new sample of the primary IMU (at ``t_us``, unless it was held)."""
        return self.imu[self.primary] if self.primary < len(self.imu) else None

    @property
    def imu_new(self) -> bool:
        """The primary IMU delivered a new sample at ``t_us`` (not a held, repeated one)."""
        s = self.primary_imu
        return s is not None and s.t_us == self.t_us
