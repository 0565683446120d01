"""FrameAssembler: decoded MAVLink messages of one vehicle -> one SI Frame per primary-IMU sample.

Timing conventions (all vehicle time, integer µs, from ``time_usec``/``time_boot_ms``):

* **Primary IMU.** HIGHRES_IMU ``id`` = instance. The primary is ``config.primary_imu`` if it is
  present, else the lowest instance present; if the primary stops (no sample for
  ``stale_after_s`` while another instance still sends) the assembler switches to that one and
  counts the switch. Without HIGHRES_IMU (real ArduPilot logs) SCALED_IMU/SCALED_IMU2/
  SCALED_IMU3 are instances 0/1/2, and RAW_IMU is instance 0 when the HEARTBEAT autopilot is
  ArduPilot (ArduPilot fills RAW_IMU with the same mG / mrad/s values); both are FRD already.
* **GPS velocity delay D** (``config.gps_delay_s``, default one GPS period at 10 Hz; in mode
  "aligned" with R = D it is a minimum, and both grow to the measured GPS period when the GPS is
  slower, so 1-10 Hz GPS all get a bracketing pair). The GPS
  velocity is linearly interpolated between the two GPS samples that bracket the query instant
  (Lu2016 sec. 5: 1 Hz interpolated to 100 Hz). Live data has no future sample, so the query
  instant lags the newest data by D: with D >= one GPS period a bracketing pair has normally
  arrived. Past the newest GPS sample the velocity is held (never extrapolated) with its age.
* **Mode "latest" (``align_delay_us`` = 0, default).** A frame is emitted as soon as its primary
  IMU sample arrives: IMU, attitude and air data are the latest values (each with its age); the
  GPS velocity is interpolated at ``t_us - D`` and ``Frame.gps_delay_us = D``. An estimator
  using it must delay its own IMU/attitude by D (a ring buffer) to compare like with like.
* **Mode "aligned" (``align_delay_us = R``, preferred with R = D).** Frames are held R and
  emitted once the newest vehicle time reaches ``t_us + R``. Each frame carries the IMU,
  attitude and air data *at its own t_us* (attitude, AoA and other time-stamped samples that
  arrive just after the IMU sample of the same instant are filled in while the frame is held),
  and the GPS velocity interpolated at ``t_us - max(0, D - R)``; with R = D that is exactly
  ``t_us`` (``gps_delay_us = 0``). ``Frame.output_delay_us = R`` says how late the frame is.
  Untimed messages (AIRSPEED, VFR_HUD) are stamped with their arrival vehicle time.
  The estimators in this repository read ``gps_vel_ned_mps`` as if taken at ``t_us``; they
  need this mode (``FrameAssembler.aligned(config, stats)``).
* ``Frame.gps_new`` is True on the first frame whose interpolation base (the newest GPS sample
  at or before the query instant) is a new sample; ``gps_age_s`` is the query instant minus
  that sample's time; ``gps_fix`` is the latest GPS_RAW_INT fix (velocity needs a 3D fix).
* ``Frame.gps_interp_err_ned_mps``: the interpolated velocity minus the velocity the primary
  IMU integrates to across the bracketing GPS interval (``samples.imu_chord``: ``tau a_mean -
  int_0^tau a``, specific force rotated by each frame's attitude). In a manoeuvre with a 1 Hz
  GPS the linear interpolation is off by up to 0.2 m/s; a constant accelerometer bias cancels.
  It needs the IMU samples of the whole interval, which the frames held in mode "aligned" (R =
  one GPS period) provide; None when they do not cover it, and never computed when no family
  reads it (``FrameAssembler(interp_error=False)``: the Monitor asks the IMU family).

**Held IMU samples.** An IMU sample whose six values (specific force and rates) repeat the
previous sample of the same instance bit for bit is a value the sender held (a stream resampled
onto a faster grid and forward-filled, a logger that found no new sensor packet): no real IMU
repeats its noise exactly, so it is no new measurement. The instance keeps its previous
:class:`ImuSample`, *with that sample's time stamp*, ``stats.imu_held`` counts it, and it never
makes an instance primary. A held sample of the primary still produces its Frame (the other
inputs and the pipeline's clock go on), whose ``imu[primary].t_us`` is then earlier than
``t_us``: consumers see the age of the IMU value and measure the *effective* IMU rate from the
new samples alone (the IMU family does, and does not step its estimators on held samples). A
primary that only repeats itself for ``stale_after_s`` while another instance delivers new
samples is switched away from, as a silent one.

Missing or stale inputs are explicit: ``None``/NaN plus an age (inf when never seen); an input
older than ``stale_after_s`` is reported invalid. Non-finite or physically impossible values are
counted per ``MESSAGE.field`` in the vehicle's :class:`LinkStats` and dropped, never passed on.
A primary-IMU clock that goes back and stays on the new time line for ``REBOOT_CONFIRM``
samples is an autopilot reboot: held frames are flushed, all state is reset, the confirming
samples are replayed, ``stats.reboots`` counts it, ``reboot_pending`` is set for the monitor and
the first new frame has ``reset=True``. A backward sample followed by a forward one is a
reordered packet (dropped, ``time_backwards``); two time lines that keep interleaving by more
than ``REBOOT_JUMP_US`` are two senders with one sysid (``clock_conflicts``,
``duplicate_sysid``), which never reset the assembler.

**Vehicle clock.** A time stamp no vehicle clock can carry is rejected and counted
(``stats.time_rejected`` and ``bad_values["MESSAGE.time_usec"]``), never passed on:

* beyond :data:`MAX_VEHICLE_T_US` (2100-01-01 as UNIX time: MAVLink's ``time_usec`` is time
  since boot or UNIX time, so no real clock is later; 2^63 and above, which no int64 holds, are
  far beyond it) or negative;
* an IMU sample more than :meth:`FrameAssembler.jump_bound_us` ahead of the IMU time line (the
  newest accepted IMU sample) and of the other streams is held, not used: if the samples that
  follow continue that later time line (``REBOOT_CONFIRM`` of them, IMU samples or those of the
  other streams), it is the vehicle's (a link outage, a clock step) and the held samples are
  replayed (``stats.time_jumps``); a sample back on the old line first means they were
  outliers, and they are dropped and counted. The bound is ``REBOOT_CONFIRM`` measured IMU
  periods: an outlier less far ahead leaves fewer than ``REBOOT_CONFIRM`` samples behind it,
  which the reboot check takes for reordered packets, so no single time stamp can fake a reboot.
  An IMU that resumes on the time line the other streams have kept (it was silent) is taken at
  once;
* a sample of another timed stream (attitude, GPS, AoA, static pressure, surfaces) more than
  that bound ahead of every stream's newest time stamp and of a held later line: the streams
  share the autopilot clock and lead each other by at most their send schedule.
"""

from __future__ import annotations

import collections
import math
from typing import Any

import numpy as np

from gcs_monitor.link.mav import mavlink
from gcs_monitor.link.stats import LinkStats
from gcs_monitor.telemetry import contract as ct
from gcs_monitor.telemetry.frame import (
    AttitudeTarget,
    Frame,
    HudSample,
    ImuSample,
    NavOutput,
    ServoOutputs,
    new_imu_sample,
)
from gcs_monitor.telemetry.period import SamplePeriod
from gcs_monitor.telemetry.samples import (
    GpsSample,
    ImuChord,
    gps_sample,
    imu_chord,
    interpolate_gps,
)

N_IMU = 3
N_AIR = 3
NEVER_US = -(1 << 62)  # "no sample yet" time stamp: ages come out astronomically large
REBOOT_JUMP_US = 1_000_000  # attitude/GPS: a step back larger than this is a clock restart
REBOOT_CONFIRM = 5  # primary-IMU samples in a row on a new, earlier time line = reboot
CLOCK_CONFLICTS_DUPLICATE = 3  # old and new time lines interleaving this often: 2 senders
REBOOT_CONFIRM_DUPLICATE = 100  # ... then only this long a run (1 s at 100 Hz) is a new clock
MAX_VEHICLE_T_US = 4_102_444_800_000_000  # 2100-01-01T00:00Z as UNIX µs (module docstring)
GPS_RING = 16  # GPS samples kept for interpolation (>= D / GPS period + 2)
DEFAULT_GPS_DELAY_S = 0.1  # one GPS period at 10 Hz (docs/telemetry.md default GPS rate)
DEFAULT_STALE_S = 0.5
SURF_BACKLOG = 64  # SURF samples kept for the next Frame (Frame.surf_new)
MAX_PENDING = 10_000  # held frames in aligned mode (100 s at 100 Hz): memory bound
GPS_FIX_3D = 3
GPS_GAP_PERIODS = 1.5  # GPS samples this many periods apart are still interpolated between
SURF_ARRAY_ID = 0
N_SURF = 3
US_PER_S = 1_000_000
S_PER_US = 1e-6

M = mavlink
_HIGHRES = M.MAVLINK_MSG_ID_HIGHRES_IMU
_RAW_IMU = M.MAVLINK_MSG_ID_RAW_IMU
_SCALED_INSTANCE = {M.MAVLINK_MSG_ID_SCALED_IMU: 0, M.MAVLINK_MSG_ID_SCALED_IMU2: 1,
                    M.MAVLINK_MSG_ID_SCALED_IMU3: 2}


# NAMED_VALUE_FLOAT names as pymavlink delivers them (bytes, NULs stripped) -> _name() of them
_AOA_NAMES = {b"AOA1": "AOA1", b"AOA2": "AOA2", "AOA1": "AOA1", "AOA2": "AOA2"}
_SURF_NAMES = frozenset({b"SURF", "SURF"})


def _dcm_ned_frd_flat(phi: float, theta: float, psi: float) -> tuple[float, ...]:
    """:func:`~gcs_monitor.core.frames.dcm_ned_frd` as a flat row-major 9-tuple of Python floats,
    with its very expressions (bit-identical, tests/gcs_monitor/telemetry/test_interp_error.py):
    many of them stack into one array, where one small array each cost more than the maths."""
    sph, cph = math.sin(phi), math.cos(phi)
    sth, cth = math.sin(theta), math.cos(theta)
    sps, cps = math.sin(psi), math.cos(psi)
    return (cth * cps, sph * sth * cps - cph * sps, cph * sth * cps + sph * sps,
            cth * sps, sph * sth * sps + cph * cps, cph * sth * sps - sph * cps,
            -sth, sph * cth, cph * cth)


def _name(raw: Any) -> str:
    if isinstance(raw, bytes):
        raw = raw.decode("ascii", errors="replace")
    return str(raw).rstrip("\x00")


class FrameAssembler:
    """Assemble Frames for one vehicle (see the module docstring for the timing conventions).

    Parameters
    ----------
    config : ``TelemetryConfig`` (``gps_delay_s``, ``stale_after_s``, ``primary_imu``) or None for
        defaults
    stats : the vehicle's link statistics (bad values, reboots, reorders are counted there)
    gps_delay_us, stale_after_s, primary_imu : override the config values
    align_delay_us : R, how long frames are held so all inputs are aligned (0: mode "latest")
    """

    def __init__(self, *, config: Any = None, stats: LinkStats | None = None,
                 gps_delay_us: int | None = None, align_delay_us: int | None = None,
                 stale_after_s: float | None = None, primary_imu: int | None = None,
                 max_pending: int = MAX_PENDING, interp_error: bool = True) -> None:
        self.stats = stats if stats is not None else LinkStats(0)
        # Frame.gps_interp_err_ned_mps is computed only for a reader (imu_ts's gps_imu_shape)
        self.interp_error = interp_error
        d_s = getattr(config, "gps_delay_s", DEFAULT_GPS_DELAY_S)
        self.gps_delay_us = int(gps_delay_us if gps_delay_us is not None else round(d_s * 1e6))
        stale_s = stale_after_s if stale_after_s is not None else getattr(
            config, "stale_after_s", DEFAULT_STALE_S)
        self.stale_us = int(round(stale_s * 1e6))
        self.stale_s = stale_s
        self.preferred_imu = int(primary_imu if primary_imu is not None else getattr(
            config, "primary_imu", 0))
        self.align_delay_us = int(align_delay_us or 0)
        if self.gps_delay_us < 0 or self.align_delay_us < 0:
            raise ValueError("gps_delay_us and align_delay_us must be >= 0")
        self.query_lag_us = max(0, self.gps_delay_us - self.align_delay_us)
        # the configured delays are minimums: with a GPS slower than 1 / D the aligned hold
        # grows to the measured GPS period, so a bracketing pair still arrives in time
        self._min_delay_us = self.gps_delay_us
        self._adapt_delay = 0 < self.align_delay_us == self.gps_delay_us
        self.max_pending = max_pending
        self._dispatch = {
            _HIGHRES: self._highres_imu,
            _RAW_IMU: self._raw_imu,
            M.MAVLINK_MSG_ID_SCALED_IMU: self._scaled_imu,
            M.MAVLINK_MSG_ID_SCALED_IMU2: self._scaled_imu,
            M.MAVLINK_MSG_ID_SCALED_IMU3: self._scaled_imu,
            M.MAVLINK_MSG_ID_ATTITUDE: self._attitude,
            M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: self._global_position,
            M.MAVLINK_MSG_ID_GPS_RAW_INT: self._gps_raw,
            M.MAVLINK_MSG_ID_AIRSPEED: self._airspeed,
            M.MAVLINK_MSG_ID_AOA_SSA: self._aoa_ssa,
            M.MAVLINK_MSG_ID_NAMED_VALUE_FLOAT: self._named_value,
            M.MAVLINK_MSG_ID_VFR_HUD: self._vfr_hud,
            M.MAVLINK_MSG_ID_SCALED_PRESSURE: self._scaled_pressure,
            M.MAVLINK_MSG_ID_DEBUG_FLOAT_ARRAY: self._debug_array,
            M.MAVLINK_MSG_ID_HEARTBEAT: self._heartbeat,
            M.MAVLINK_MSG_ID_SERVO_OUTPUT_RAW: self._servo_output,
            M.MAVLINK_MSG_ID_NAV_CONTROLLER_OUTPUT: self._nav_output,
            M.MAVLINK_MSG_ID_ATTITUDE_TARGET: self._attitude_target,
        }
        self.seen: set[str] = set()  # contract messages accepted at least once (availability)
        self.ignored = 0
        self.reboot_pending = False
        self.frames_out = 0
        self.autopilot = -1
        # availability bookkeeping survives resets
        self._ever_imu: set[int] = set()
        self._ever_aoa: set[int] = set()
        self._ever_cas: set[int] = set()
        self._imu_source = "none"
        self._ever_surf = False
        self._reset()

    @classmethod
    def aligned(cls, config: Any = None, stats: LinkStats | None = None,
                **kw: Any) -> FrameAssembler:
        """Mode "aligned" with R = D: every input of a frame, GPS included, is at ``t_us``."""
        d_s = getattr(config, "gps_delay_s", DEFAULT_GPS_DELAY_S)
        d_us = int(kw.pop("gps_delay_us", round(d_s * 1e6)))
        return cls(config=config, stats=stats, gps_delay_us=d_us, align_delay_us=d_us, **kw)

    # -- state -------------------------------------------------------------------------------
    def _reset(self) -> None:
        self._imu: list[ImuSample | None] = [None] * N_IMU  # latest new sample per instance
        self._imu_vals: list[tuple[float, ...]] = [()] * N_IMU  # its six values (held check)
        self._imu_t = [NEVER_US] * N_IMU  # latest message time per instance (clock checks)
        self._imu_line = NEVER_US  # the IMU time line: max(self._imu_t), kept with it
        self._imu_msg = [0] * N_IMU  # message id feeding each instance (one source each)
        self._highres = False
        self._primary: int | None = None
        self._reboot_buf: collections.deque[tuple[int, int, float, float, float, float, float,
                                                  float]] = collections.deque(
                                                      maxlen=REBOOT_CONFIRM)
        self._back_run = 0
        # IMU samples held on a later time line (module docstring, "Vehicle clock")
        self._jump_buf: list[tuple[str, int, int, float, float, float, float, float,
                                   float]] = []
        self._line_period = SamplePeriod()  # of the IMU time line (distinct accepted instants)
        self._jump_us = REBOOT_JUMP_US  # jump_bound_us(), recomputed when the period moves
        self._other_t = NEVER_US  # newest accepted time stamp of the other timed streams
        self._jump_support = 0  # other-stream samples on the held later line
        self._last_frame_t = NEVER_US
        self._now_us = NEVER_US
        self._att: np.ndarray | None = None
        self._att_rate: np.ndarray | None = None
        self._att_t = NEVER_US
        self._gps: collections.deque[GpsSample] = collections.deque(maxlen=GPS_RING)
        self._gps_fix = -1
        self._gps_base_t = NEVER_US
        self._gps_period = SamplePeriod()  # measured GPS period: the aligned hold follows it
        # recent frames (their primary IMU sample and attitude) and the IMU chord of the GPS
        # interval being interpolated across (samples.imu_chord)
        self._chord_frames: collections.deque[Frame] = collections.deque(maxlen=MAX_PENDING)
        self._chord: ImuChord | None = None
        self._chord_key = (NEVER_US, NEVER_US)
        # AoA vanes 0..2 then CAS 0..2 in one list each (one array per frame, four views)
        self._air_v = [math.nan] * (2 * N_AIR)
        self._air_marked_us = NEVER_US  # newest air sample instant already marked air_new
        self._air_t = [NEVER_US] * (2 * N_AIR)
        self._air_new = False
        self._air_period = SamplePeriod()  # of the air-data sample instants (air_new marks)
        self._ssa = math.nan
        self._ssa_t = NEVER_US
        self._baro_alt = self._climb = math.nan
        self._baro_t = NEVER_US
        self._p_static = math.nan
        self._p_static_t = NEVER_US
        self._oat = math.nan
        self._surf: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self._surf_t = NEVER_US
        # the SURF samples not yet handed to a Frame (Frame.surf_new), bounded: a Frame
        # slower than SURF by more than this keeps the newest
        self._surf_backlog: collections.deque[tuple[int, np.ndarray, np.ndarray, np.ndarray]] \
            = collections.deque(maxlen=SURF_BACKLOG)
        # control telemetry (samples stamped with their vehicle time; see _control_fields)
        self._servo: ServoOutputs | None = None
        self._nav: NavOutput | None = None
        self._att_target: AttitudeTarget | None = None
        self._hud: HudSample | None = None
        self._pending: collections.deque[Frame] = collections.deque()
        self._next_reset_flag = False

    # -- input -------------------------------------------------------------------------------
    def push(self, msg: Any) -> list[Frame]:
        """Consume one decoded message of this vehicle; return the Frames completed by it."""
        handler = self._dispatch.get(msg._header.msgId)
        if handler is None:
            self.ignored += 1
            return []
        return handler(msg)

    def push_many(self, msgs: Any) -> list[Frame]:
        """``push`` for a sequence of messages."""
        out: list[Frame] = []
        for m in msgs:
            f = self.push(m)
            if f:
                out += f
        return out

    def flush(self) -> list[Frame]:
        """End of input: emit every held frame with what is known (aligned mode)."""
        out = []
        while self._pending:
            out.append(self._finish(self._pending.popleft()))
        return out

    def _bad(self, msg: str, names: tuple[str, ...], vals: tuple[float, ...],
             lo: tuple[float, ...], hi: tuple[float, ...]) -> list[Frame]:
        """Count each offending field of a rejected message (slow path only)."""
        for n, v, a, b in zip(names, vals, lo, hi, strict=True):
            if not a <= v <= b:  # False for NaN too
                self.stats.bad_value(f"{msg}.{n}")
        return []

    # IMU ----------------------------------------------------------------------------------------
    def _heartbeat(self, m: Any) -> list[Frame]:
        if m._header.srcComponent == 1 or self.autopilot < 0:
            self.autopilot = int(m.autopilot)
        return []

    def _highres_imu(self, m: Any) -> list[Frame]:
        if not self._highres:
            self._highres = True  # HIGHRES_IMU present: the fallbacks are ignored from now on
            self._imu_msg = [_HIGHRES] * N_IMU
            self._imu_source = "HIGHRES_IMU"
        inst = m.id
        ax, ay, az, p, q, r = m.xacc, m.yacc, m.zacc, m.xgyro, m.ygyro, m.zgyro
        A, W = ct.MAX_ACC_MPS2, ct.MAX_RATE_RADPS
        if not (-A <= ax <= A and -A <= ay <= A and -A <= az <= A
                and -W <= p <= W and -W <= q <= W and -W <= r <= W):
            return self._bad("HIGHRES_IMU", ("xacc", "yacc", "zacc", "xgyro", "ygyro", "zgyro"),
                             (ax, ay, az, p, q, r), (-A,) * 3 + (-W,) * 3, (A,) * 3 + (W,) * 3)
        if not 0 <= inst < N_IMU:
            self.stats.bad_value("HIGHRES_IMU.id")
            return []
        return self._imu_in("HIGHRES_IMU.time_usec", m.time_usec, inst, ax, ay, az, p, q, r)

    def _fallback_imu(self, m: Any, name: str, inst: int, t_us: int) -> list[Frame]:
        msg_id = m._header.msgId
        owner = self._imu_msg[inst]
        if owner == 0:
            self._imu_msg[inst] = owner = msg_id
            if self._imu_source == "none":
                self._imu_source = name
        if owner != msg_id:  # RAW_IMU and SCALED_IMU both describe IMU 0: keep the first
            return []
        k, g = ct.MG_TO_MPS2, ct.MRAD_TO_RAD
        ax, ay, az = m.xacc * k, m.yacc * k, m.zacc * k
        p, q, r = m.xgyro * g, m.ygyro * g, m.zgyro * g
        A, W = ct.MAX_ACC_MPS2, ct.MAX_RATE_RADPS
        if not (-A <= ax <= A and -A <= ay <= A and -A <= az <= A
                and -W <= p <= W and -W <= q <= W and -W <= r <= W):
            return self._bad(name, ("xacc", "yacc", "zacc", "xgyro", "ygyro", "zgyro"),
                             (ax, ay, az, p, q, r), (-A,) * 3 + (-W,) * 3, (A,) * 3 + (W,) * 3)
        field = ".time_usec" if msg_id == _RAW_IMU else ".time_boot_ms"
        return self._imu_in(name + field, t_us, inst, ax, ay, az, p, q, r)

    def _scaled_imu(self, m: Any) -> list[Frame]:
        if self._highres:
            return []
        inst = _SCALED_INSTANCE[m._header.msgId]
        return self._fallback_imu(m, m._type, inst, m.time_boot_ms * ct.MS_TO_US)

    def _raw_imu(self, m: Any) -> list[Frame]:
        # RAW_IMU is raw sensor counts in general; ArduPilot fills it with mG and mrad/s.
        if self._highres or self.autopilot != M.MAV_AUTOPILOT_ARDUPILOTMEGA:
            return []
        return self._fallback_imu(m, "RAW_IMU", 0, int(m.time_usec))

    # vehicle clock ------------------------------------------------------------------------------
    def jump_bound_us(self) -> int:
        """How far ahead of the IMU time line an IMU sample may be before it is held:
        ``REBOOT_CONFIRM`` measured line periods (``REBOOT_JUMP_US`` until measured)."""
        return self._jump_us

    def _line_instant(self, t_us: int) -> None:
        """A new instant of the IMU time line: into its period, and the jump bound with it."""
        period = self._line_period
        period.add(t_us)
        if period.known:
            self._jump_us = int(REBOOT_CONFIRM * period.seconds() * US_PER_S)

    def _time_rejected(self, key: str, n: int = 1) -> None:
        self.stats.bad_value(key, n)
        self.stats.time_rejected += n

    def _bad_time(self, key: str, t_us: int) -> bool:
        """Reject (True, counted) a time stamp no clock can carry, or a timed sample of another
        stream too far ahead of the vehicle's time line (module docstring)."""
        if not 0 <= t_us <= MAX_VEHICLE_T_US:
            self._time_rejected(key)
            return True
        line = max(self._imu_line, self._other_t)
        lim = self._jump_us
        if line == NEVER_US or t_us - line <= lim:
            if t_us > self._other_t:
                self._other_t = t_us
            return False
        buf = self._jump_buf
        if buf and abs(t_us - buf[-1][1]) <= lim:  # on the held later line: it confirms it
            self._jump_support += 1
            self._other_t = t_us
            return False
        self._time_rejected(key)
        return True

    def _imu_in(self, key: str, t_us: int, inst: int, ax: float, ay: float, az: float,
                p: float, q: float, r: float) -> list[Frame]:
        """Clock check of one IMU sample (module docstring, "Vehicle clock"), then
        :meth:`_imu_sample`. ``key`` names the time field for the counters."""
        if not 0 <= t_us <= MAX_VEHICLE_T_US:
            self._time_rejected(key)
            return []
        line = self._imu_line
        buf = self._jump_buf
        bound = self._jump_us
        if line != NEVER_US and t_us - line > bound:
            if not buf and self._other_t != NEVER_US and t_us - self._other_t <= bound:
                # the other streams are on this time line already: the IMU was silent, not
                # wrong (no interval is measured across its gap)
                self._line_period.gap()
                return self._accept_imu(t_us, inst, ax, ay, az, p, q, r)
            if buf and abs(t_us - buf[-1][1]) > bound:
                self._drop_held()  # not the held line either: those were outliers
            buf.append((key, t_us, inst, ax, ay, az, p, q, r))
            if len(buf) + self._jump_support < REBOOT_CONFIRM:
                return []
            # confirmed: the vehicle's clock is on the later line (an outage, a clock step)
            self.stats.time_jumps += 1
            self._line_period.gap()
            held = list(buf)
            buf.clear()
            self._jump_support = 0
            out: list[Frame] = []
            for _, *sample in held:
                out += self._accept_imu(*sample)  # type: ignore[arg-type]
            return out
        if buf:
            self._drop_held()  # back on the current line: the held samples were outliers
        # the usual case, :meth:`_accept_imu` inline (``line`` is still the newest IMU time)
        out = self._imu_sample(t_us, inst, ax, ay, az, p, q, r)
        if t_us > line and self._imu_t[inst] == t_us:  # a new instant of the time line
            self._line_instant(t_us)
        return out

    def _accept_imu(self, t_us: int, inst: int, ax: float, ay: float, az: float, p: float,
                    q: float, r: float) -> list[Frame]:
        """:meth:`_imu_sample`, then the period of the IMU time line on a new instant of it."""
        newest = self._imu_line
        out = self._imu_sample(t_us, inst, ax, ay, az, p, q, r)
        if t_us > newest and self._imu_t[inst] == t_us:  # a new instant of the time line
            self._line_instant(t_us)
        return out

    def _drop_held(self) -> None:
        for key, *_ in self._jump_buf:
            self._time_rejected(key)
        self._jump_buf.clear()
        self._jump_support = 0

    def _imu_sample(self, t_us: int, inst: int, ax: float, ay: float, az: float, p: float,
                    q: float, r: float) -> list[Frame]:
        st = self.stats
        last = self._imu_t[inst]
        primary = self._primary
        if t_us <= last:
            if t_us == last:
                st.duplicates_dropped += 1
                return []
            st.time_backwards += 1
            if inst != primary:
                return []
            # primary clock went back: a reboot once REBOOT_CONFIRM samples in a row continue
            # the new time line; a forward sample in between means a reordered packet (or,
            # for big jumps, a second sender with the same sysid)
            buf = self._reboot_buf
            if buf and t_us <= buf[-1][0]:
                buf.clear()
                self._back_run = 0
            buf.append((t_us, inst, ax, ay, az, p, q, r))  # bounded deque: replayed on reboot
            self._back_run += 1
            # with two senders on this sysid, only a long run on the earlier clock (the other
            # sender has stopped) is taken as the new time line
            need = REBOOT_CONFIRM_DUPLICATE if st.duplicate_sysid else REBOOT_CONFIRM
            if self._back_run >= need:
                return self._reboot()
            return []
        if self._back_run and inst == primary:
            if self._imu_t[inst] - self._reboot_buf[0][0] > REBOOT_JUMP_US:
                st.clock_conflicts += 1  # two clocks interleave: two senders, one sysid
                if st.clock_conflicts >= CLOCK_CONFLICTS_DUPLICATE:
                    st.duplicate_sysid = True
            self._reboot_buf.clear()
            self._back_run = 0
        vals = (ax, ay, az, p, q, r)
        held = vals == self._imu_vals[inst]  # module docstring, "Held IMU samples"
        if held:
            st.imu_held += 1
            sample = self._imu[inst]
        else:
            v6 = np.array(vals)  # one allocation, two views
            sample = new_imu_sample(t_us, inst, v6[:3], v6[3:])
            self._imu[inst] = sample
            self._imu_vals[inst] = vals
        self._imu_t[inst] = t_us  # later than this instance's last: the line only advances
        if t_us > self._imu_line:
            self._imu_line = t_us
        self._ever_imu.add(inst)
        if inst != primary:
            if held:
                return []
            # the primary's newest *new* sample: one that only repeats itself is silent too
            last_new = self._imu[primary] if primary is not None else None
            if (primary is None or inst == self.preferred_imu
                    or (inst < primary and primary != self.preferred_imu)
                    or last_new is None or t_us - last_new.t_us > self.stale_us):
                if primary is not None:
                    st.primary_imu_switches += 1
                self._primary = primary = inst
            else:
                if self._pending:  # fill the held frames of the same instant
                    for f in reversed(self._pending):
                        if f.t_us < t_us:
                            break
                        f.imu[inst] = sample
                return []
        if t_us <= self._last_frame_t:
            return []
        if t_us > self._now_us:
            self._now_us = t_us
        if st.last_vehicle_t_us < t_us:
            st.last_vehicle_t_us = t_us
        self._last_frame_t = t_us
        frame = self._new_frame(t_us)
        ring = self._chord_frames
        ring.append(frame)
        gps_s = self._gps_period.seconds()
        # an interval that starts before this is never interpolated across again
        keep_us = self.align_delay_us + self.stale_us + (
            0 if gps_s != gps_s else round(GPS_GAP_PERIODS * gps_s * US_PER_S))
        while ring[0].t_us < t_us - keep_us:
            ring.popleft()
        if self.align_delay_us == 0:
            return [self._finish(frame)]
        pend = self._pending
        pend.append(frame)
        out: list[Frame] = []
        horizon = t_us - self.align_delay_us
        while pend and (pend[0].t_us <= horizon or len(pend) > self.max_pending):
            out.append(self._finish(pend.popleft()))
        return out

    def _reboot(self) -> list[Frame]:
        buf = list(self._reboot_buf)
        out = self.flush()
        self.stats.reboots += 1
        self.stats.time_backwards -= len(buf)  # these samples are replayed, not dropped
        highres, src = self._highres, self._imu_msg
        self._reset()
        self._highres, self._imu_msg = highres, src
        self.reboot_pending = True
        self._next_reset_flag = True
        for sample in buf:
            out += self._imu_sample(*sample)
        return out

    # attitude and GPS ---------------------------------------------------------------------------
    def _attitude(self, m: Any) -> list[Frame]:
        ph, th, ps = m.roll, m.pitch, m.yaw
        E = ct.MAX_ANGLE_RAD
        if not (-E <= ph <= E and -E <= th <= E and -E <= ps <= E):
            return self._bad("ATTITUDE", ("roll", "pitch", "yaw"), (ph, th, ps), (-E,) * 3,
                             (E,) * 3)
        t_us = m.time_boot_ms * ct.MS_TO_US
        if self._bad_time("ATTITUDE.time_boot_ms", t_us):
            return []
        if t_us < self._att_t:
            if self._att_t - t_us <= REBOOT_JUMP_US:
                self.stats.time_backwards += 1
                return []
            # a larger jump: the attitude clock restarted; the IMU decides about reboots
        e = np.array((ph, th, ps))
        if self._att is None:
            self.seen.add("ATTITUDE")
        self._att = e
        self._att_t = t_us
        w = self._attitude_rates(m)
        if self._pending:
            for f in reversed(self._pending):
                if f.t_us < t_us:
                    break
                age = (f.t_us - t_us) * S_PER_US
                if age < f.att_age_s:
                    f.euler_rad = e
                    f.att_rate_frd_radps = w
                    f.att_age_s = age
        return []

    def _attitude_rates(self, m: Any) -> np.ndarray | None:
        """ATTITUDE rollspeed, pitchspeed, yawspeed (body FRD, rad/s), or None when implausible
        (counted); stored with the attitude they came with."""
        p, q, r = m.rollspeed, m.pitchspeed, m.yawspeed
        W = ct.MAX_RATE_RADPS
        if not (-W <= p <= W and -W <= q <= W and -W <= r <= W):
            self._bad("ATTITUDE", ("rollspeed", "pitchspeed", "yawspeed"), (p, q, r),
                      (-W,) * 3, (W,) * 3)
            self._att_rate = None
            return None
        self._att_rate = np.array((p, q, r))
        return self._att_rate

    def _gps_raw(self, m: Any) -> list[Frame]:
        self._gps_fix = int(m.fix_type)
        return []

    def _global_position(self, m: Any) -> list[Frame]:
        t_us = m.time_boot_ms * ct.MS_TO_US
        if self._bad_time("GLOBAL_POSITION_INT.time_boot_ms", t_us):
            return []
        s = ct.CMPS_TO_MPS
        vn, ve, vd = m.vx * s, m.vy * s, m.vz * s
        V = ct.MAX_SPEED_MPS
        if not (-V <= vn <= V and -V <= ve <= V and -V <= vd <= V):
            return self._bad("GLOBAL_POSITION_INT", ("vx", "vy", "vz"), (vn, ve, vd),
                             (-V,) * 3, (V,) * 3)
        lat, lon, alt = m.lat * ct.DEGE7_TO_RAD, m.lon * ct.DEGE7_TO_RAD, m.alt * ct.MM_TO_M
        half_pi = 0.5 * math.pi
        if not (-half_pi <= lat <= half_pi and -math.pi <= lon <= math.pi
                and ct.MIN_ALT_M <= alt <= ct.MAX_ALT_M):
            self._bad("GLOBAL_POSITION_INT", ("lat", "lon", "alt"), (lat, lon, alt),
                      (-half_pi, -math.pi, ct.MIN_ALT_M), (half_pi, math.pi, ct.MAX_ALT_M))
            # Hold the last valid position: it changes slowly, and NaN would poison the
            # estimators' earth-rate and gravity terms (and so reset them) for one bad field.
            prev = next((g for g in reversed(self._gps) if g.lat_rad == g.lat_rad), None)
            lat, lon, alt = ((prev.lat_rad, prev.lon_rad, prev.alt_msl_m) if prev is not None
                             else (math.nan, math.nan, math.nan))
        ring = self._gps
        if ring:
            last = ring[-1].t_us
            if t_us <= last:
                if last - t_us > REBOOT_JUMP_US:
                    ring.clear()  # GPS clock restarted; the IMU decides about reboots
                elif t_us == last:
                    self.stats.duplicates_dropped += 1
                    return []
                else:
                    self.stats.time_backwards += 1
                    return []
        if not ring:
            self.seen.add("GLOBAL_POSITION_INT")
        ring.append(gps_sample(t_us, vn, ve, vd, lat, lon, alt))
        self._gps_period.add(t_us)
        if self._adapt_delay and self._gps_period.known:
            d_us = max(self._min_delay_us, round(self._gps_period.seconds() * US_PER_S))
            if d_us != self.gps_delay_us:
                self.gps_delay_us = self.align_delay_us = d_us
        return []

    # air data and surfaces ----------------------------------------------------------------------
    def _airspeed(self, m: Any) -> list[Frame]:
        i = m.id
        v = m.airspeed
        V = ct.MAX_SPEED_MPS
        if not 0.0 <= v <= V:
            return self._bad("AIRSPEED", ("airspeed",), (v,), (0.0,), (V,))
        if not 0 <= i < N_AIR:
            self.stats.bad_value("AIRSPEED.id")
            return []
        self._ever_cas.add(i)
        self._set_air(N_AIR + i, self._now_us, v)  # untimed: stamped with its arrival time
        oat = m.temperature * ct.CDEGC_TO_K + ct.ZERO_C_K
        if ct.MIN_OAT_K <= oat <= ct.MAX_OAT_K:
            self._oat = oat
        return []

    def _set_aoa(self, i: int, t_us: int, aoa: float) -> None:
        self._ever_aoa.add(i)
        self._set_air(i, t_us, aoa)

    def _set_air(self, k: int, t_us: int, value: float) -> None:
        """Store air-data value ``k`` (AoA 0..2, then CAS 0..2) sampled at ``t_us``.

        Held frames at or after the sample instant get the value (its messages may arrive after
        the IMU sample of the same instant). Exactly one frame per air sample carries
        ``air_new``: the first held frame at or after the instant, or, when none is held (mode
        "latest", or a sample newer than every frame), the next frame built. The air-data FDI
        steps on ``air_new``, so a sample split over several messages is one step, not several.
        """
        self._air_v[k] = value
        self._air_t[k] = t_us
        first = None
        if self._pending:
            aoa = k < N_AIR
            j = k if aoa else k - N_AIR
            for f in reversed(self._pending):
                if f.t_us < t_us:
                    break
                age = (f.t_us - t_us) * S_PER_US
                ages = f.aoa_age_s if aoa else f.cas_age_s
                if age < ages[j]:
                    (f.aoa_rad if aoa else f.cas_mps)[j] = value
                    ages[j] = age
                first = f
        if first is None:
            self._air_new = True
            self._air_period.add(t_us)
        elif t_us > self._air_marked_us:
            first.air_new = True
            self._air_marked_us = t_us
            self._air_period.add(t_us)

    def _aoa_ssa(self, m: Any) -> list[Frame]:
        k = ct.DEG_TO_RAD
        a, b = m.AOA * k, m.SSA * k
        L = ct.MAX_AOA_RAD
        t_us = int(m.time_usec)
        if self._bad_time("AOA_SSA.time_usec", t_us):
            return []
        if -L <= b <= L:
            if self._ssa_t == NEVER_US:
                self.seen.add("AOA_SSA")
            self._ssa, self._ssa_t = b, t_us
        else:
            self.stats.bad_value("AOA_SSA.SSA")
        if not -L <= a <= L:
            return self._bad("AOA_SSA", ("AOA",), (a,), (-L,), (L,))
        self._set_aoa(0, t_us, a)
        return []

    def _named_value(self, m: Any) -> list[Frame]:
        raw = m.name
        name = _AOA_NAMES.get(raw) if isinstance(raw, (bytes, str)) else None
        if name is None:
            name = _name(raw)
            if name not in ("AOA1", "AOA2"):
                return []
        a = m.value * ct.DEG_TO_RAD
        L = ct.MAX_AOA_RAD
        if not -L <= a <= L:
            return self._bad("NAMED_VALUE_FLOAT", (name,), (a,), (-L,), (L,))
        t_us = m.time_boot_ms * ct.MS_TO_US
        if self._bad_time("NAMED_VALUE_FLOAT.time_boot_ms", t_us):
            return []
        self._set_aoa(1 if name == "AOA1" else 2, t_us, a)
        return []

    def _vfr_hud(self, m: Any) -> list[Frame]:
        self._hud_fields(m)
        alt, climb = m.alt, m.climb
        V = ct.MAX_SPEED_MPS
        if not (ct.MIN_ALT_M <= alt <= ct.MAX_ALT_M and -V <= climb <= V):
            return self._bad("VFR_HUD", ("alt", "climb"), (alt, climb), (ct.MIN_ALT_M, -V),
                             (ct.MAX_ALT_M, V))
        if self._baro_t == NEVER_US:
            self.seen.add("VFR_HUD")
        self._baro_alt, self._climb = alt, climb
        self._baro_t = self._now_us
        return []

    def _scaled_pressure(self, m: Any) -> list[Frame]:
        p = m.press_abs * ct.HPA_TO_PA
        if not ct.MIN_PRESSURE_PA <= p <= ct.MAX_PRESSURE_PA:
            return self._bad("SCALED_PRESSURE", ("press_abs",), (p,), (ct.MIN_PRESSURE_PA,),
                             (ct.MAX_PRESSURE_PA,))
        t_us = m.time_boot_ms * ct.MS_TO_US
        if self._bad_time("SCALED_PRESSURE.time_boot_ms", t_us):
            return []
        if self._p_static_t == NEVER_US:
            self.seen.add("SCALED_PRESSURE")
        self._p_static = p
        self._p_static_t = t_us
        oat = m.temperature * ct.CDEGC_TO_K + ct.ZERO_C_K
        if ct.MIN_OAT_K <= oat <= ct.MAX_OAT_K:
            self._oat = oat
        else:
            self.stats.bad_value("SCALED_PRESSURE.temperature")
        return []

    def _debug_array(self, m: Any) -> list[Frame]:
        if m.array_id != SURF_ARRAY_ID:
            return []
        nm = m.name
        if not (isinstance(nm, (bytes, str)) and nm in _SURF_NAMES) and _name(nm) != "SURF":
            return []
        raw = m.data
        d = np.array(raw[:3 * N_SURF], dtype=float)
        cmd, pos, rod = d[0::3], d[1::3], d[2::3]
        S, R = ct.MAX_SURF_RAD, ct.MAX_ROD_M
        # |cmd|, |pos| <= S and |rod| <= R on Python floats (False for NaN), cheaper than numpy
        ok = True
        for j, v in enumerate(d.tolist()):
            if not abs(v) <= (R if j % 3 == 2 else S):
                ok = False
                break
        if not ok:
            names = tuple(f"data[{j}]" for j in range(3 * N_SURF))
            lims = (S, S, R) * N_SURF
            return self._bad("DEBUG_FLOAT_ARRAY.SURF", names, tuple(d.tolist()),
                             tuple(-x for x in lims), lims)
        t_us = int(m.time_usec)
        if self._bad_time("DEBUG_FLOAT_ARRAY.time_usec", t_us):
            return []
        if t_us == self._surf_t or 0 < self._surf_t - t_us <= REBOOT_JUMP_US:
            return []  # a repeated or reordered SURF sample is no new one
        self._surf = (cmd, pos, rod)
        self._ever_surf = True
        self._surf_t = t_us
        self._surf_backlog.append((t_us, cmd, pos, rod))
        return []

    # control telemetry: servo outputs, setpoints, throttle ------------------------------------
    # Stamped with the vehicle time they arrive at (NAV_CONTROLLER_OUTPUT and VFR_HUD carry no
    # time; SERVO_OUTPUT_RAW's 32-bit time_usec wraps after 71 min); ATTITUDE_TARGET with its
    # time_boot_ms. Frames built from then on carry the latest sample and its age.
    def _servo_output(self, m: Any) -> list[Frame]:
        if getattr(m, "port", 0):  # outputs 1-16 are port 0 (a PX4 log's other output groups:
            return []  # their channel numbers mean other things)
        pwm: list[float] = []
        for k in range(1, 17):
            v = getattr(m, f"servo{k}_raw", 0)  # servo9..16: MAVLink 2 extensions
            if v in ct.PWM_UNUSED:
                pwm.append(math.nan)
            elif 0 < v <= ct.MAX_PWM_US:
                pwm.append(float(v))
            else:
                self.stats.bad_value(f"SERVO_OUTPUT_RAW.servo{k}_raw")
                pwm.append(math.nan)
        c, h = ct.PWM_CENTER_US, ct.PWM_HALF_RANGE_US
        if self._servo is None:
            self.seen.add("SERVO_OUTPUT_RAW")
        self._servo = ServoOutputs(self._now_us, tuple(pwm), tuple((x - c) / h for x in pwm))
        return []

    def _nav_output(self, m: Any) -> list[Frame]:
        k = ct.DEG_TO_RAD
        ang = (m.nav_roll * k, m.nav_pitch * k)
        E, V, A, X = ct.MAX_ANGLE_RAD, ct.MAX_SPEED_MPS, ct.MAX_ALT_M, ct.MAX_DIST_M
        if not (-E <= ang[0] <= E and -E <= ang[1] <= E and -A <= m.alt_error <= A
                and -V <= m.aspd_error <= V and -X <= m.xtrack_error <= X):
            return self._bad("NAV_CONTROLLER_OUTPUT",
                             ("nav_roll", "nav_pitch", "alt_error", "aspd_error", "xtrack_error"),
                             (ang[0], ang[1], m.alt_error, m.aspd_error, m.xtrack_error),
                             (-E, -E, -A, -V, -X), (E, E, A, V, X))
        if self._nav is None:
            self.seen.add("NAV_CONTROLLER_OUTPUT")
        self._nav = NavOutput(self._now_us, ang[0], ang[1], m.nav_bearing * k,
                              m.target_bearing * k, float(m.wp_dist), float(m.alt_error),
                              float(m.aspd_error), float(m.xtrack_error))
        return []

    def _attitude_target(self, m: Any) -> list[Frame]:
        mask = int(m.type_mask)
        nan = math.nan
        euler: tuple[float, float, float] | None = None
        if not mask & 0x80:  # bit 7: attitude ignored
            w, x, y, z = (float(v) for v in m.q)
            n = math.sqrt(w * w + x * x + y * y + z * z)
            if not 0.5 < n < 1.5:  # not a rotation (also False for NaN)
                return self._bad("ATTITUDE_TARGET", ("q",), (n,), (0.5,), (1.5,))
            w, x, y, z = w / n, x / n, y / n, z / n
            euler = (math.atan2(2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y)),
                     -math.asin(max(-1.0, min(1.0, 2.0 * (x * z - w * y)))),
                     math.atan2(2.0 * (x * y + w * z), 1.0 - 2.0 * (y * y + z * z)))
        W = ct.MAX_RATE_RADPS
        rates = []
        for bit, v, name in ((1, m.body_roll_rate, "body_roll_rate"),
                             (2, m.body_pitch_rate, "body_pitch_rate"),
                             (4, m.body_yaw_rate, "body_yaw_rate")):
            if mask & bit:
                rates.append(nan)
            elif -W <= v <= W:
                rates.append(float(v))
            else:
                self.stats.bad_value(f"ATTITUDE_TARGET.{name}")
                rates.append(nan)
        thrust = nan if mask & 0x40 or not -1.0 <= m.thrust <= 1.0 else float(m.thrust)
        if self._att_target is None:
            self.seen.add("ATTITUDE_TARGET")
        self._att_target = AttitudeTarget(m.time_boot_ms * ct.MS_TO_US, euler,
                                          (rates[0], rates[1], rates[2]), thrust)
        return []

    def _hud_fields(self, m: Any) -> None:
        """VFR_HUD airspeed, ground speed, heading and throttle (altitude and climb: _vfr_hud)."""
        V = ct.MAX_SPEED_MPS
        a, gs, thr = m.airspeed, m.groundspeed, m.throttle * ct.PCT_TO_FRAC
        if not (0.0 <= a <= V and 0.0 <= gs <= V and 0.0 <= thr <= 1.0):
            self._bad("VFR_HUD", ("airspeed", "groundspeed", "throttle"), (a, gs, thr),
                      (0.0, 0.0, 0.0), (V, V, 1.0))
            return
        if self._hud is None:
            self.seen.add("VFR_HUD.throttle")
        self._hud = HudSample(self._now_us, float(a), float(gs), m.heading * ct.DEG_TO_RAD,
                              thr)

    def _control_fields(self, f: Frame, t_us: int) -> None:
        """The latest control samples on a new frame, with their ages (None when stale)."""
        stale = self.stale_s
        if self._servo is not None:
            f.servo_age_s = age = (t_us - self._servo.t_us) * S_PER_US
            f.servo = self._servo if age <= stale else None
        if self._nav is not None:
            f.nav_age_s = age = (t_us - self._nav.t_us) * S_PER_US
            f.nav = self._nav if age <= stale else None
        if self._att_target is not None:
            f.att_target_age_s = age = (t_us - self._att_target.t_us) * S_PER_US
            f.att_target = self._att_target if age <= stale else None
        if self._hud is not None:
            f.hud_age_s = age = (t_us - self._hud.t_us) * S_PER_US
            f.hud = self._hud if age <= stale else None

    # -- output ------------------------------------------------------------------------------
    def _new_frame(self, t_us: int) -> Frame:
        """Snapshot of the latest inputs at primary-IMU time ``t_us`` (GPS added in _finish).

        Python floats on the hot path: three-element numpy arithmetic costs more than it saves.
        """
        stale = self.stale_s
        nan = math.nan
        ages = [(t_us - x) * S_PER_US for x in self._air_t]
        vals = [v if a <= stale else nan for v, a in zip(self._air_v, ages, strict=True)]
        air = np.array(vals + ages)  # [aoa 0..2, cas 0..2, aoa ages, cas ages]
        n = N_AIR
        att_age = (t_us - self._att_t) * S_PER_US
        baro_age = (t_us - self._baro_t) * S_PER_US
        baro_ok = baro_age <= stale
        surf_age = (t_us - self._surf_t) * S_PER_US
        surf = self._surf if surf_age <= stale else None
        f = Frame(
            t_us, list(self._imu),
            self._att if att_age <= stale else None,
            att_age if self._att is not None else math.inf,
            aoa_rad=air[0:n], aoa_age_s=air[2 * n:3 * n], cas_mps=air[n:2 * n],
            cas_age_s=air[3 * n:4 * n], air_new=self._air_new,
            ssa_rad=self._ssa if (t_us - self._ssa_t) * S_PER_US <= stale else nan,
            baro_alt_m=self._baro_alt if baro_ok else nan,
            climb_mps=self._climb if baro_ok else nan,
            air_age_s=min(min(ages), baro_age),
            static_pressure_pa=(self._p_static if (t_us - self._p_static_t) * S_PER_US <= stale
                                else nan),
            oat_k=self._oat,
            surf_cmd_rad=surf[0] if surf else None, surf_pos_rad=surf[1] if surf else None,
            rod_pos_m=surf[2] if surf else None, surf_age_s=surf_age,
            surf_new=self._take_surf() if self._surf_backlog else (),
            reset=self._next_reset_flag, gps_fix=self._gps_fix,
            primary=self._primary if self._primary is not None else 0,
            att_rate_frd_radps=self._att_rate if att_age <= stale else None,
            mav_type=self.stats.mav_type,
        )
        if self._servo is not None or self._nav is not None or self._hud is not None \
                or self._att_target is not None:
            self._control_fields(f, t_us)
        self._air_new = False
        self._next_reset_flag = False
        return f

    def _take_surf(self) -> tuple[tuple[int, np.ndarray, np.ndarray, np.ndarray], ...]:
        """The SURF samples since the previous Frame (Frame.surf_new), then none pending."""
        out = tuple(self._surf_backlog)
        self._surf_backlog.clear()
        return out

    def _finish(self, f: Frame) -> Frame:
        """Attach the GPS velocity interpolated at ``t_us - query_lag`` (module docstring)."""
        lag = self.query_lag_us
        # a slower GPS is interpolated across its own period (1 Hz GPS: 1 s between samples)
        gps_s = self._gps_period.seconds()
        max_gap = (self.stale_us if gps_s != gps_s
                   else max(self.stale_us, round(GPS_GAP_PERIODS * gps_s * US_PER_S)))
        g = interpolate_gps(self._gps, f.t_us - lag, max_gap, self.stale_us)
        f.gps_period_s = gps_s
        f.gps_delay_us = lag
        f.output_delay_us = self.align_delay_us
        f.gps_age_s = g.age_s
        if g.base is not None:
            f.lat_rad, f.lon_rad, f.alt_msl_m = g.base.lat_rad, g.base.lon_rad, g.base.alt_msl_m
            if g.base.t_us != self._gps_base_t:
                self._gps_base_t = g.base.t_us
                f.gps_new = True
        fix_ok = self._gps_fix < 0 or self._gps_fix >= GPS_FIX_3D
        f.gps_vel_ned_mps = g.vel_ned_mps if fix_ok else None
        f.gps_held = g.vel_ned_mps is not None and not g.interpolated
        if g.interpolated and g.base is not None and g.upper is not None and fix_ok \
                and self.interp_error:
            f.gps_interp_err_ned_mps = self._interp_error(g.base.t_us, g.upper.t_us,
                                                          f.t_us - lag)
        f.gps_fix = self._gps_fix
        # measured when the frame leaves: samples that arrived while it was held count
        f.air_period_s = self._air_period.seconds()
        self.frames_out += 1
        return f

    def _interp_error(self, t0_us: int, t1_us: int, t_us: int) -> np.ndarray | None:
        """The interpolated GPS velocity's error at ``t_us`` from the IMU across the GPS
        interval ``[t0_us, t1_us]`` (samples.imu_chord), computed once per interval from the
        held frames' primary-IMU samples rotated by their attitude; None when they do not
        cover the interval."""
        if (t0_us, t1_us) != self._chord_key:
            self._chord_key = (t0_us, t1_us)
            ring = self._chord_frames
            while len(ring) > 1 and ring[1].t_us <= t0_us:  # later intervals start later
                ring.popleft()
            ts: list[int] = []
            dcm: list[tuple[float, ...]] = []
            acc_frd: list[np.ndarray] = []
            for fr in ring:
                if fr.t_us > t1_us and ts and ts[-1] >= t1_us:
                    break
                imu = fr.imu[fr.primary] if fr.primary < len(fr.imu) else None
                if imu is None or imu.t_us != fr.t_us or fr.euler_rad is None:
                    continue  # a held IMU value or no attitude: no sample of the shape
                e = fr.euler_rad.tolist()
                ts.append(fr.t_us)
                dcm.append(_dcm_ned_frd_flat(e[0], e[1], e[2]))
                acc_frd.append(imu.acc_frd_mps2)
            if len(ts) >= 2:
                # all samples' C_ned_frd @ a_frd in one call: a stacked matmul runs the same
                # BLAS gemv per (3, 3) @ (3, 1) item as ``dcm_ned_frd(...) @ acc`` per sample
                # did, so the values are bit-identical (a Python dot product is not: the BLAS
                # kernel uses fused multiply-adds)
                acc = np.matmul(np.array(dcm).reshape(-1, 3, 3), np.array(acc_frd)[:, :, None])
                self._chord = imu_chord(ts, acc[:, :, 0], t0_us, t1_us)
            else:
                self._chord = None
        return None if self._chord is None else self._chord.error_at(t_us)

    # -- reporting ---------------------------------------------------------------------------
    def availability(self) -> dict[str, Any]:
        """Which inputs this vehicle's telemetry carries (see :func:`input_availability`)."""
        s = self.seen
        return {
            "imu_instances": len(self._ever_imu), "imu_ids": sorted(self._ever_imu),
            "imu_source": self._imu_source, "primary_imu": self._primary,
            "attitude": "ATTITUDE" in s, "gps_velocity": "GLOBAL_POSITION_INT" in s,
            "aoa_instances": len(self._ever_aoa), "aoa_ids": sorted(self._ever_aoa),
            "cas_instances": len(self._ever_cas), "cas_ids": sorted(self._ever_cas),
            "ssa": "AOA_SSA" in s, "baro": "VFR_HUD" in s,
            "static_pressure": "SCALED_PRESSURE" in s,
            "surfaces": self._ever_surf,
            "body_rates": self._att_rate is not None,
            "servo_outputs": "SERVO_OUTPUT_RAW" in s,
            "nav_setpoints": "NAV_CONTROLLER_OUTPUT" in s,
            "attitude_target": "ATTITUDE_TARGET" in s,
            "throttle": "VFR_HUD.throttle" in s,
            "commands": "SERVO_OUTPUT_RAW" in s or "NAV_CONTROLLER_OUTPUT" in s,
            "frames": self.frames_out,
        }


def input_availability(source: FrameAssembler | Any) -> dict[str, Any]:
    """Which inputs are present: IMU instances, attitude, GPS velocity, AoA, CAS, surfaces.

    ``source`` is a :class:`FrameAssembler` (what it has seen) or an iterable of Frames (what
    they carry valid at least once). Keys: ``imu_instances``/``aoa_instances``/``cas_instances``
    (counts), ``imu_ids``/``aoa_ids``/``cas_ids`` (instance lists), ``attitude``,
    ``gps_velocity``, ``ssa``, ``baro``, ``static_pressure``, ``surfaces``, ``body_rates``,
    ``servo_outputs``, ``nav_setpoints``, ``attitude_target``, ``throttle``, ``commands`` (servo
    outputs or setpoints) (bools), ``frames``.
    """
    if isinstance(source, FrameAssembler):
        return source.availability()
    imu: set[int] = set()
    aoa = np.zeros(N_AIR, dtype=bool)
    cas = np.zeros(N_AIR, dtype=bool)
    att = gps = ssa = baro = static = surf = False
    rates = servo = nav = target = thr = False
    n = 0
    for f in source:
        n += 1
        for s in f.imu:
            if s is not None:
                imu.add(s.instance)
        att = att or f.euler_rad is not None
        gps = gps or f.gps_vel_ned_mps is not None
        aoa |= np.isfinite(f.aoa_rad[:N_AIR])
        cas |= np.isfinite(f.cas_mps[:N_AIR])
        ssa = ssa or math.isfinite(f.ssa_rad)
        baro = baro or math.isfinite(f.baro_alt_m)
        static = static or math.isfinite(f.static_pressure_pa)
        surf = surf or f.surf_pos_rad is not None
        rates = rates or f.att_rate_frd_radps is not None
        servo = servo or f.servo is not None
        nav = nav or f.nav is not None
        target = target or f.att_target is not None
        thr = thr or f.hud is not None
    aoa_ids = [int(i) for i in np.flatnonzero(aoa)]
    cas_ids = [int(i) for i in np.flatnonzero(cas)]
    return {"imu_instances": len(imu), "imu_ids": sorted(imu), "attitude": att,
            "gps_velocity": gps, "aoa_instances": len(aoa_ids), "aoa_ids": aoa_ids,
            "cas_instances": len(cas_ids), "cas_ids": cas_ids, "ssa": ssa, "baro": baro,
            "static_pressure": static, "surfaces": surf, "body_rates": rates,
            "servo_outputs": servo, "nav_setpoints": nav, "attitude_target": target,
            "throttle": thr, "commands": servo or nav, "frames": n}
