"""The Frame: one fixed-rate snapshot per IMU sample, in SI units and NED/FRD frames.

Slow inputs (air data, GPS, attitude) are held with their age; GPS ground velocity is linearly
interpolated to the IMU time with a bounded, documented delay (see ``assembler.py``).
A missing input is ``None`` or NaN with an explicit validity flag, never a silent zero.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any

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


def slot_setters(cls: type) -> tuple[Any, ...]:
    """The slot descriptors' setters of a frozen slots dataclass, in field order: the hot
    paths build such objects with ``object.__new__`` and these (a frozen dataclass's
    ``__init__`` sets each field through ``object.__setattr__``, more than twice the cost)."""
    return tuple(getattr(cls, f.name).__set__ for f in fields(cls))


_new = object.__new__
_IMU_SET = slot_setters(ImuSample)


def new_imu_sample(t_us: int, instance: int, acc_frd_mps2: Vec3,
                   omega_frd_radps: Vec3) -> ImuSample:
    """``ImuSample(t_us, instance, acc_frd_mps2, omega_frd_radps)``, built at less than half the
    cost for the assembler's hot path (three per Frame): a frozen dataclass's ``__init__`` sets
    each field through ``object.__setattr__``; this sets the same slots through their
    descriptors. The object is the same (fields, equality, hash, repr)."""
    s = _new(ImuSample)
    t, i, a, w = _IMU_SET
    t(s, t_us)
    i(s, instance)
    a(s, acc_frd_mps2)
    w(s, omega_frd_radps)
    return s


@dataclass(frozen=True, slots=True)
class ServoOutputs:
    """One SERVO_OUTPUT_RAW: the autopilot's output channels 1..16.

    t_us : vehicle time the message arrived (its ``time_usec`` is 32 bits and wraps)
    pwm_us : (16,) pulse width per output channel, µs; NaN where the channel is unused
        (0 or 65535) or absent (servo9..16 are MAVLink 2 extensions)
    norm : (16,) ``(pwm - 1500) / 500``: -1..1 around the standard centre (a surface's own
        trim and throw, and the throttle's 1000-2000 µs range, are the families' business)
    """

    t_us: int
    pwm_us: tuple[float, ...]
    norm: tuple[float, ...]


@dataclass(frozen=True, slots=True)
class NavOutput:
    """One NAV_CONTROLLER_OUTPUT: the autopilot's attitude setpoints and tracking errors, SI.

    t_us : vehicle time the message arrived (the message has no time stamp)
    nav_roll_rad, nav_pitch_rad : commanded bank and pitch
    nav_bearing_rad, target_bearing_rad : commanded heading, bearing to the target
    wp_dist_m : distance to the active waypoint
    alt_error_m, aspd_error_mps, xtrack_error_m : altitude, airspeed and cross-track errors
        (MAVLink: commanded minus current for altitude and airspeed)
    """

    t_us: int
    nav_roll_rad: float
    nav_pitch_rad: float
    nav_bearing_rad: float
    target_bearing_rad: float
    wp_dist_m: float
    alt_error_m: float
    aspd_error_mps: float
    xtrack_error_m: float


@dataclass(frozen=True, slots=True)
class AttitudeTarget:
    """One ATTITUDE_TARGET: the attitude controller's setpoint, SI; what its ``type_mask``
    says to ignore is None / NaN.

    euler_rad : (phi, theta, psi) of the target quaternion (ZYX, NED -> FRD), or None
    rate_frd_radps : (p, q, r) body-rate setpoints, NaN where ignored
    thrust : collective thrust setpoint 0..1 (NaN when ignored)
    """

    t_us: int
    euler_rad: tuple[float, float, float] | None
    rate_frd_radps: tuple[float, float, float]
    thrust: float


@dataclass(frozen=True, slots=True)
class HudSample:
    """The VFR_HUD fields besides altitude and climb (those are ``Frame.baro_alt_m`` /
    ``climb_mps``): what the autopilot shows the pilot, SI.

    airspeed_mps : the autopilot's airspeed (indicated; ground speed on a copter)
    throttle : 0..1 (MAVLink: percent)
    """

    t_us: int
    airspeed_mps: float
    groundspeed_mps: float
    heading_rad: float
    throttle: float


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
    att_rate_frd_radps : (3,) body rates of the ATTITUDE message (the autopilot's estimate,
        aligned with ``euler_rad``), or None
    servo, nav, att_target, hud : the latest SERVO_OUTPUT_RAW, NAV_CONTROLLER_OUTPUT,
        ATTITUDE_TARGET and VFR_HUD control fields (None when never received or older than
        the stale limit); ``*_age_s`` their ages (inf when never received). A family sees a
        new sample by its ``t_us``.
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
    # interpolated GPS velocity minus the velocity the IMU integrates to across the bracketing
    # GPS interval (samples.imu_chord): the interpolation error in a manoeuvre, NED m/s; None
    # when not interpolated or the IMU and attitude do not cover the interval
    gps_interp_err_ned_mps: Vec3 | None = None
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
    # every SURF sample that arrived since the previous Frame, oldest first, as (t_us, cmd,
    # pos, rod): with Frames slower than SURF (IMU 25 Hz, SURF 50 Hz) the latest alone
    # would lose samples. Empty when none arrived; the surf_* fields are the newest
    surf_new: tuple[tuple[int, Vec, Vec, Vec], ...] = ()
    # added by the assembler (telemetry room); see assembler.py for the delay conventions
    output_delay_us: int = 0  # how far behind the newest received vehicle time this frame is
    gps_fix: int = -1  # GPS_RAW_INT fix_type (-1: no GPS_RAW_INT seen); velocity needs >= 3
    reset: bool = False  # first frame after an assembler reset (autopilot reboot)
    # the IMU instance whose sample this frame is (it switches when the primary goes silent)
    primary: int = 0
    mav_type: int = -1  # the vehicle's HEARTBEAT type (MAV_TYPE), -1 before one arrived
    # control telemetry (actuator family): body rates of ATTITUDE, servo outputs, setpoints
    att_rate_frd_radps: Vec3 | None = None
    servo: ServoOutputs | None = None
    servo_age_s: float = float("inf")
    nav: NavOutput | None = None
    nav_age_s: float = float("inf")
    att_target: AttitudeTarget | None = None
    att_target_age_s: float = float("inf")
    hud: HudSample | None = None
    hud_age_s: float = float("inf")

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
