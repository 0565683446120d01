"""FrameAssembler: decoded MAVLink messages -> one SI Frame per sample of the primary IMU.

GPS ground velocity is linearly interpolated to each IMU time between the two GPS samples that
bracket it (Lu2016 sec. 5: 1 Hz interpolated to 100 Hz). To never look into the future of live
data, a Frame is held until the GPS sample after its time has arrived; the delay is therefore
bounded by one GPS period plus transport latency (``Frame.gps_delay_us`` reports it), and at most
``max_wait_s`` (then the frame is emitted with the last GPS velocity held and its age). All other
inputs are sampled at the IMU time (latest value and its age). Attitude that arrives after the
IMU sample of the same timestamp is patched into the held frame, so IMU and attitude are aligned.

Vehicle time comes from ``time_usec``/``time_boot_ms`` as int µs. Time going backwards by more
than ``reboot_jump_s`` is an autopilot reboot: state is reset and ``reboot_pending`` is set for the
monitor to reset the estimators. Non-finite or physically impossible values are counted in the
link statistics and dropped, never passed on (and so never become fault alarms).
"""

from __future__ import annotations

import collections
import math
from typing import Any

import numpy as np

from gcs_monitor.core.units import CM2M, DEG2RAD, DEGE7_2RAD, HPA2PA, MM2M
from gcs_monitor.link.mav import mavlink
from gcs_monitor.link.stats import LinkStats
from gcs_monitor.telemetry import contract as ct
from gcs_monitor.telemetry.frame import Frame, ImuSample

REBOOT_JUMP_US = 1_000_000
N_AIR = 3
N_IMU = 3


class FrameAssembler:
    """Assemble Frames for one vehicle.

    Parameters
    ----------
    stats : the vehicle's link statistics (bad values, reorders, reboots are counted there)
    max_wait_s : longest a frame waits for the next GPS sample
    stale_after_s : inputs older than this are reported invalid (NaN / None)
    """

    def __init__(self, stats: LinkStats | None = None, *, max_wait_s: float = 1.5,
                 stale_after_s: float = 0.5, max_pending: int = 2000) -> None:
        self.stats = stats if stats is not None else LinkStats(0)
        self.max_wait_us = int(max_wait_s * 1e6)
        self.stale_us = int(stale_after_s * 1e6)
        self.max_pending = max_pending
        self._dispatch = {
            mavlink.MAVLINK_MSG_ID_HIGHRES_IMU: self._highres_imu,
            mavlink.MAVLINK_MSG_ID_SCALED_IMU: self._scaled_imu,
            mavlink.MAVLINK_MSG_ID_SCALED_IMU2: self._scaled_imu,
            mavlink.MAVLINK_MSG_ID_SCALED_IMU3: self._scaled_imu,
            mavlink.MAVLINK_MSG_ID_ATTITUDE: self._attitude,
            mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: self._global_position,
            mavlink.MAVLINK_MSG_ID_AIRSPEED: self._airspeed,
            mavlink.MAVLINK_MSG_ID_AOA_SSA: self._aoa_ssa,
            mavlink.MAVLINK_MSG_ID_NAMED_VALUE_FLOAT: self._named_value,
            mavlink.MAVLINK_MSG_ID_VFR_HUD: self._vfr_hud,
            mavlink.MAVLINK_MSG_ID_SCALED_PRESSURE: self._scaled_pressure,
            mavlink.MAVLINK_MSG_ID_DEBUG_FLOAT_ARRAY: self._debug_array,
        }
        self._scaled_ids = {mavlink.MAVLINK_MSG_ID_SCALED_IMU: 0,
                            mavlink.MAVLINK_MSG_ID_SCALED_IMU2: 1,
                            mavlink.MAVLINK_MSG_ID_SCALED_IMU3: 2}
        self.seen: collections.Counter[str] = collections.Counter()
        self.reboot_pending = False
        self.frames_out = 0
        self._reset()

    def _reset(self) -> None:
        self._imu: list[ImuSample | None] = [None] * N_IMU
        self._highres = False
        self._primary: int | None = None
        self._last_t_us = -1
        self._now_us = 0
        self._att: np.ndarray | None = None
        self._att_t = -1
        self._gps_prev: tuple[int, np.ndarray] | None = None
        self._gps_last: tuple[int, np.ndarray] | None = None
        self._lat = self._lon = self._alt = math.nan
        self._aoa = np.full(N_AIR, np.nan)
        self._aoa_t = np.full(N_AIR, -(10**15), dtype=np.int64)
        self._cas = np.full(N_AIR, np.nan)
        self._cas_t = np.full(N_AIR, -(10**15), dtype=np.int64)
        self._air_new = False
        self._ssa = math.nan
        self._baro_alt = self._climb = math.nan
        self._air_t = -(10**15)
        self._p_static = self._oat = math.nan
        self._surf: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self._surf_t = -(10**15)
        self._pending: collections.deque[Frame] = collections.deque()
        self._gps_seen_since_frame = False

    # -- input -------------------------------------------------------------------------------
    def push(self, msg: Any) -> list[Frame]:
        """Consume one decoded message; return the Frames that became complete."""
        handler = self._dispatch.get(msg._header.msgId)
        if handler is None:
            return []
        self.seen[msg._type] += 1
        return handler(msg)

    def flush(self) -> list[Frame]:
        """End of input: emit every held frame with what is known."""
        out = []
        while self._pending:
            out.append(self._finish(self._pending.popleft()))
        return out

    def _bad(self, name: str) -> list[Frame]:
        self.stats.bad_value(name)
        return []

    def _highres_imu(self, m: Any) -> list[Frame]:
        self._highres = True
        return self._imu_sample(int(m.time_usec), int(m.id), m.xacc, m.yacc, m.zacc,
                                m.xgyro, m.ygyro, m.zgyro, 1.0, 1.0)

    def _scaled_imu(self, m: Any) -> list[Frame]:
        if self._highres:
            return []
        inst = self._scaled_ids[m._header.msgId]
        return self._imu_sample(int(m.time_boot_ms) * 1000, inst, m.xacc, m.yacc, m.zacc,
                                m.xgyro, m.ygyro, m.zgyro, ct.MG_TO_MPS2, ct.MRAD_TO_RAD)

    def _imu_sample(self, t_us: int, inst: int, ax: float, ay: float, az: float, p: float,
                    q: float, r: float, ka: float, kg: float) -> list[Frame]:
        if not 0 <= inst < N_IMU:
            return self._bad("imu.instance")
        vals = (ax, ay, az, p, q, r)
        if not all(math.isfinite(v) for v in vals):
            return self._bad("imu.nan")
        ax, ay, az = ax * ka, ay * ka, az * ka
        p, q, r = p * kg, q * kg, r * kg
        if max(abs(ax), abs(ay), abs(az)) > ct.MAX_ACC_MPS2 or max(abs(p), abs(q), abs(r)) > \
                ct.MAX_RATE_RADPS:
            return self._bad("imu.range")
        if self._primary is None or inst < self._primary:
            self._primary = inst
        if inst != self._primary:
            self._imu[inst] = ImuSample(t_us, inst, np.array((ax, ay, az)), np.array((p, q, r)))
            return []
        last = self._last_t_us
        if last >= 0 and t_us <= last:
            if last - t_us > REBOOT_JUMP_US:
                out = self.flush()
                self.stats.reboots += 1
                self._reset()
                self.reboot_pending = True
                return out + self._imu_sample(t_us, inst, ax / ka, ay / ka, az / ka, p / kg,
                                              q / kg, r / kg, ka, kg)
            if t_us == last:
                self.stats.duplicates_dropped += 1
            else:
                self.stats.time_reorders += 1
            return []
        self._last_t_us = t_us
        self._now_us = max(self._now_us, t_us)
        sample = ImuSample(t_us, inst, np.array((ax, ay, az)), np.array((p, q, r)))
        self._imu[inst] = sample
        frame = self._new_frame(t_us)
        self._pending.append(frame)
        return self._release()

    def _attitude(self, m: Any) -> list[Frame]:
        e = (m.roll, m.pitch, m.yaw)
        if not all(math.isfinite(v) and abs(v) <= 2 * math.pi + 0.1 for v in e):
            return self._bad("attitude")
        t_us = int(m.time_boot_ms) * 1000
        self._att = np.array(e)
        self._att_t = t_us
        # patch held frames of the same (ms-rounded) time that were built before it arrived
        for f in reversed(self._pending):
            if abs(f.t_us - t_us) < 1000:
                f.euler_rad = self._att
                f.att_age_s = 0.0
            elif f.t_us < t_us:
                break
        return []

    def _global_position(self, m: Any) -> list[Frame]:
        t_us = int(m.time_boot_ms) * 1000
        v = np.array((m.vx * CM2M, m.vy * CM2M, m.vz * CM2M))
        lat, lon, alt = m.lat * DEGE7_2RAD, m.lon * DEGE7_2RAD, m.alt * MM2M
        if abs(lat) > math.pi / 2 or abs(lon) > math.pi or not ct.MIN_ALT_M < alt < ct.MAX_ALT_M:
            self.stats.bad_value("gps.position")
        else:
            self._lat, self._lon, self._alt = lat, lon, alt
        if self._gps_last is not None and t_us <= self._gps_last[0]:
            if self._gps_last[0] - t_us > REBOOT_JUMP_US:
                self._gps_prev = self._gps_last = None
            else:
                return self._bad("gps.time_order")
        if float(np.max(np.abs(v))) > ct.MAX_SPEED_MPS:
            return self._bad("gps.velocity")
        self._gps_prev = self._gps_last
        self._gps_last = (t_us, v)
        self._gps_seen_since_frame = True
        return self._release()

    def _airspeed(self, m: Any) -> list[Frame]:
        i = int(m.id)
        if not 0 <= i < N_AIR:
            return self._bad("airspeed.instance")
        v = float(m.airspeed)
        if not math.isfinite(v) or not 0.0 <= v < ct.MAX_SPEED_MPS:
            return self._bad("airspeed.range")
        self._cas[i] = v
        self._cas_t[i] = self._now_us
        self._air_new = True
        t = float(m.temperature)
        if math.isfinite(t) and t != 0:
            self._oat = t * ct.CDEGC_TO_K + ct.ZERO_C_K
        return []

    def _set_aoa(self, i: int, deg: float) -> list[Frame]:
        a = deg * DEG2RAD
        if not math.isfinite(a) or abs(a) > ct.MAX_AOA_RAD:
            return self._bad("aoa.range")
        self._aoa[i] = a
        self._aoa_t[i] = self._now_us
        self._air_new = True
        return []

    def _aoa_ssa(self, m: Any) -> list[Frame]:
        s = m.SSA * DEG2RAD
        if math.isfinite(s) and abs(s) <= ct.MAX_AOA_RAD:
            self._ssa = s
        return self._set_aoa(0, m.AOA)

    def _named_value(self, m: Any) -> list[Frame]:
        name = m.name if isinstance(m.name, str) else m.name.decode(errors="replace")
        name = name.rstrip("\x00")
        if name in ("AOA1", "AOA2"):
            return self._set_aoa(int(name[3]), m.value)
        return []

    def _vfr_hud(self, m: Any) -> list[Frame]:
        alt, climb = float(m.alt), float(m.climb)
        if not (math.isfinite(alt) and math.isfinite(climb)) or not \
                ct.MIN_ALT_M < alt < ct.MAX_ALT_M or abs(climb) > ct.MAX_SPEED_MPS:
            return self._bad("vfr_hud")
        self._baro_alt, self._climb = alt, climb
        self._air_t = self._now_us
        return []

    def _scaled_pressure(self, m: Any) -> list[Frame]:
        p = float(m.press_abs) * HPA2PA
        if not math.isfinite(p) or not 1_000.0 < p < 120_000.0:
            return self._bad("pressure")
        self._p_static = p
        self._oat = float(m.temperature) * ct.CDEGC_TO_K + ct.ZERO_C_K
        return []

    def _debug_array(self, m: Any) -> list[Frame]:
        name = m.name if isinstance(m.name, str) else m.name.decode(errors="replace")
        if name.rstrip("\x00") != "SURF":
            return []
        d = np.asarray(m.data[:9], dtype=float)
        if not np.all(np.isfinite(d)):
            return self._bad("surf")
        self._surf = (d[0::3].copy(), d[1::3].copy(), d[2::3].copy())
        self._surf_t = self._now_us
        return []

    # -- output ------------------------------------------------------------------------------
    def _new_frame(self, t_us: int) -> Frame:
        stale = self.stale_us
        aoa_age = (t_us - self._aoa_t) * 1e-6
        cas_age = (t_us - self._cas_t) * 1e-6
        aoa = np.where(aoa_age * 1e6 <= stale, self._aoa, np.nan)
        cas = np.where(cas_age * 1e6 <= stale, self._cas, np.nan)
        att_ok = self._att is not None and t_us - self._att_t <= stale
        surf = self._surf if t_us - self._surf_t <= stale else None
        f = Frame(
            t_us=t_us, imu=list(self._imu),
            euler_rad=self._att if att_ok else None,
            att_age_s=(t_us - self._att_t) * 1e-6 if self._att is not None else math.inf,
            lat_rad=self._lat, lon_rad=self._lon, alt_msl_m=self._alt,
            aoa_rad=aoa, aoa_age_s=aoa_age.astype(float), cas_mps=cas,
            cas_age_s=cas_age.astype(float), air_new=self._air_new, ssa_rad=self._ssa,
            baro_alt_m=self._baro_alt if t_us - self._air_t <= stale else math.nan,
            climb_mps=self._climb if t_us - self._air_t <= stale else math.nan,
            air_age_s=(t_us - self._air_t) * 1e-6,
            static_pressure_pa=self._p_static, oat_k=self._oat,
            surf_cmd_rad=surf[0] if surf else None, surf_pos_rad=surf[1] if surf else None,
            rod_pos_m=surf[2] if surf else None, surf_age_s=(t_us - self._surf_t) * 1e-6,
        )
        self._air_new = False
        return f

    def _release(self) -> list[Frame]:
        out: list[Frame] = []
        pend = self._pending
        g = self._gps_last
        while pend:
            f = pend[0]
            if g is not None and f.t_us <= g[0]:
                out.append(self._finish(pend.popleft()))
            elif self._now_us - f.t_us > self.max_wait_us or len(pend) > self.max_pending:
                out.append(self._finish(pend.popleft()))
            else:
                break
        return out

    def _finish(self, f: Frame) -> Frame:
        """Attach the GPS velocity at the frame's time (interpolated, or held with its age)."""
        t = f.t_us
        g1, g0 = self._gps_last, self._gps_prev
        f.gps_delay_us = max(0, self._now_us - t)
        if g1 is not None and g0 is not None and g0[0] <= t <= g1[0]:
            w = (t - g0[0]) / (g1[0] - g0[0])
            f.gps_vel_ned_mps = g0[1] + w * (g1[1] - g0[1])
            f.gps_age_s = (t - g0[0]) * 1e-6
        elif g1 is not None and t >= g1[0]:
            age = (t - g1[0]) * 1e-6
            f.gps_age_s = age
            f.gps_vel_ned_mps = g1[1] if age * 1e6 <= self.stale_us else None
        elif g0 is not None and t < g0[0]:
            f.gps_age_s = math.inf  # older than anything bracketing it (start of data)
            f.gps_vel_ned_mps = None
        if self._gps_seen_since_frame and f.gps_vel_ned_mps is not None:
            f.gps_new = True
            self._gps_seen_since_frame = False
        self.frames_out += 1
        return f

    def availability(self) -> dict[str, Any]:
        """Which inputs this vehicle's telemetry carries (for 'which estimators can run')."""
        s = self.seen
        n_imu = sum(1 for x in self._imu if x is not None)
        n_aoa = int(np.sum(self._aoa_t > -(10**14)))
        n_cas = int(np.sum(self._cas_t > -(10**14)))
        return {
            "imu_instances": n_imu, "imu_source": "HIGHRES_IMU" if self._highres else
            ("SCALED_IMU" if n_imu else "none"),
            "attitude": s["ATTITUDE"] > 0, "gps_velocity": s["GLOBAL_POSITION_INT"] > 0,
            "aoa_instances": n_aoa, "cas_instances": n_cas, "baro": s["VFR_HUD"] > 0,
            "surfaces": s["DEBUG_FLOAT_ARRAY"] > 0,
        }
