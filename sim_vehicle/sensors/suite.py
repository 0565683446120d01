"""The aircraft's sensors: sample the true state at each sensor's rate, add noise, apply faults.

Sensor groups (one seeded ``numpy.random.Generator`` and one rate each):

========== ============================================================ ==========================
group      channels (SI)                                                 true value (TrueState)
========== ============================================================ ==========================
imu<i>     acc.x/y/z [m/s^2], gyro.p/q/r [rad/s], body FRD               acc_frd_mps2, omega_frd
attitude   phi, theta, psi [rad] (independent Euler measurement)         euler_rad
gps        vel.n/e/d [m/s], lat, lon [rad], alt [m]                      vel_ned_mps, lat/lon/alt
baro       alt [m] (pressure altitude), vs [m/s] (positive up)           pressure_alt_m, -v_D
airdata    aoa0..2 [rad], cas0..2 [m/s] (triplex), ssa [rad]             aoa_rad, cas_mps, ssa_rad
static     static.p [Pa], oat [K]                                        static_pressure_pa, oat_k
========== ============================================================ ==========================

GPS is sampled (no interpolation; the monitor interpolates) and may lag the truth by a fixed
latency: the value reported at ``t`` is the true value at ``t - latency``.
"""

from __future__ import annotations

import math
import zlib
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from gcs_monitor.core.constants import EARTH_RADIUS_M
from gcs_monitor.core.types import Vec
from sim_vehicle.faults.profiles import FaultInjector, FaultSpec
from sim_vehicle.sensors.channels import N_AIRDATA, group_channels, sensor_groups
from sim_vehicle.sensors.noise import SensorNoise, SensorSet
from sim_vehicle.state import TrueState

_NOISE_BLOCK = 1024  # rows of noise drawn at once per group (deterministic, faster)


def true_values(group: str, s: TrueState) -> Vec:
    """The noise-free measurement vector of a group (order of ``group_channels``)."""
    if group.startswith("imu"):
        return np.concatenate((s.acc_frd_mps2, s.omega_frd_radps))
    if group == "attitude":
        return np.asarray(s.euler_rad, dtype=float)
    if group == "gps":
        v = s.vel_ned_mps
        return np.array([v[0], v[1], v[2], s.lat_rad, s.lon_rad, s.alt_m])
    if group == "baro":
        return np.array([s.pressure_alt_m, -s.vel_ned_mps[2]])
    if group == "airdata":
        return np.array([s.aoa_rad] * N_AIRDATA + [s.cas_mps] * N_AIRDATA + [s.ssa_rad])
    if group == "static":
        return np.array([s.static_pressure_pa, s.oat_k])
    raise KeyError(group)


def group_sigma(group: str, n: SensorNoise, lat_rad: float = 0.0) -> Vec:
    """1-sigma noise per channel of a group (SI). GPS lat/lon sigma depends on latitude."""
    if group.startswith("imu"):
        return np.array([n.acc_mps2] * 3 + [n.gyro_radps] * 3)
    if group == "attitude":
        return np.array(n.euler_rad, dtype=float)
    if group == "gps":
        sig_lat = n.gps_pos_m / EARTH_RADIUS_M
        sig_lon = sig_lat / max(math.cos(lat_rad), 1e-6)
        return np.array([n.gps_vel_mps] * 3 + [sig_lat, sig_lon, n.gps_alt_m])
    if group == "baro":
        return np.array([n.baro_alt_m, n.vs_mps])
    if group == "airdata":
        return np.array([n.aoa_rad] * N_AIRDATA + [n.cas_mps] * N_AIRDATA + [n.ssa_rad])
    if group == "static":
        return np.array([n.static_pa, n.oat_k])
    raise KeyError(group)


def group_rate_hz(group: str, sset: SensorSet) -> float:
    r = sset.rates
    if group.startswith("imu"):
        return r.imu_hz
    return float(getattr(r, f"{group}_hz"))


def group_seed(seed: int, group: str) -> np.random.SeedSequence:
    """Stable per-sensor-instance seed (crc32 of the group name, not Python's salted hash)."""
    return np.random.SeedSequence([seed, zlib.crc32(group.encode())])


@dataclass(frozen=True, slots=True)
class SensorSample:
    """One sample of one sensor group."""

    group: str
    t_us: int  # vehicle time of the sample
    values: Vec  # measured, SI, order of ``group_channels(group)``


@dataclass
class _Group:
    name: str
    channels: list[str]
    period_us: int
    sigma: Vec
    rng: np.random.Generator
    next_due_us: int = 0
    faulted: list[tuple[int, str]] = field(default_factory=list)  # (index, channel)
    scaled: bool = True  # blocks hold sigma * noise (False: unit noise, sigma varies)
    _block: Vec = field(default_factory=lambda: np.empty((0, 0)))
    _row: int = 0

    def noise(self) -> Vec:
        """The next noise row: ``sigma * N(0, 1)`` (unit normal if not ``scaled``)."""
        if self._row >= self._block.shape[0]:
            self._block = self.rng.standard_normal((_NOISE_BLOCK, len(self.channels)))
            if self.scaled:
                self._block *= self.sigma
            self._row = 0
        row: Vec = self._block[self._row]
        self._row += 1
        return row


class SensorSuite:
    """All sensors of one aircraft.

    Parameters
    ----------
    sensor_set : noise and rates (``LU2016``, ``ATMACA2025`` or a modified copy)
    n_imu : number of IMU instances, 1..3
    faults : sensor faults to apply
    seed : scenario seed; each sensor group draws from its own generator derived from it
    gps_latency_s : GPS reports the true value this long ago (0 = none)
    record_faults : keep ``fault_log`` (time and applied fault value per faulted channel)
    """

    def __init__(
        self,
        sensor_set: SensorSet,
        *,
        n_imu: int = 1,
        faults: tuple[FaultSpec, ...] = (),
        seed: int = 0,
        gps_latency_s: float = 0.0,
        record_faults: bool = True,
    ) -> None:
        self.sensor_set = sensor_set
        self.n_imu = n_imu
        self.injector = FaultInjector(tuple(faults), seed)
        self.gps_latency_us = round(gps_latency_s * 1e6)
        self._gps_hist: deque[tuple[int, Vec]] = deque()
        self.record_faults = record_faults
        self.fault_log: dict[str, tuple[list[float], list[float]]] = {}
        self.groups: list[_Group] = []
        faulted = set(self.injector.channels)
        for g in sensor_groups(n_imu):
            chans = [c for c, _ in group_channels(g)]
            grp = _Group(
                name=g,
                channels=chans,
                period_us=round(1e6 / group_rate_hz(g, sensor_set)),
                sigma=group_sigma(g, sensor_set.noise),
                rng=np.random.default_rng(group_seed(seed, g)),
            )
            grp.scaled = g != "gps"
            grp.faulted = [(i, c) for i, c in enumerate(chans) if c in faulted]
            for _, c in grp.faulted:
                self.fault_log[c] = ([], [])
            self.groups.append(grp)

    def step(self, state: TrueState, t_us: int) -> list[SensorSample]:
        """Samples of every group due at ``t_us`` (the time of ``state``)."""
        out: list[SensorSample] = []
        if self.gps_latency_us > 0:
            self._gps_hist.append((t_us, true_values("gps", state)))
            while len(self._gps_hist) > 1 and self._gps_hist[1][0] <= t_us - self.gps_latency_us:
                self._gps_hist.popleft()
        imu_true: Vec | None = None  # shared by the IMU instances
        for g in self.groups:
            if t_us < g.next_due_us:
                continue
            g.next_due_us += g.period_us
            if g.next_due_us <= t_us:  # a rate above the step rate: resynchronise, never burst
                g.next_due_us = t_us + g.period_us
            name = g.name
            if name == "gps":
                x = self._gps_hist[0][1] if self.gps_latency_us > 0 else true_values("gps", state)
                y = x + group_sigma("gps", self.sensor_set.noise, float(x[3])) * g.noise()
            else:
                if name[:3] == "imu":
                    if imu_true is None:
                        imu_true = true_values(name, state)
                    x = imu_true
                else:
                    x = true_values(name, state)
                y = x + g.noise()  # the block is already scaled by sigma
            if g.faulted:
                t_s = t_us * 1e-6
                for i, ch in g.faulted:
                    healthy = float(y[i])
                    yi = self.injector.apply(ch, t_s, float(x[i]), healthy)
                    if yi < 0.0 and ch[:3] == "cas":
                        # CAS comes from the pitot-static pressure difference: a biased or
                        # drifting probe reads 0, never a negative airspeed
                        yi = 0.0
                    y[i] = yi
                    if self.record_faults:
                        ts, fv = self.fault_log[ch]
                        ts.append(t_s)
                        fv.append(yi - healthy)
            out.append(SensorSample(name, t_us, y))
        return out
