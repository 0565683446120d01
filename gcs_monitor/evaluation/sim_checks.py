"""Issue-2 checks of the simulator as tables: trim hold, Dryden PSD, eq. 11 consistency, noise.

``gcs-monitor evaluate --experiment sim_physics`` prints them (the unit tests assert the same
properties; this command reports the numbers for docs/results.md).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
from scipy import signal

from gcs_monitor.evaluation.report import md_table
from gcs_monitor.models.kinematics import gs_km_f
from sim_vehicle.environment.wind import DrydenTurbulence, dryden_psd
from sim_vehicle.physics import InitialCondition, ManoeuvreConfig, Simulation, WindConfig
from sim_vehicle.sensors.noise import ATMACA2025, LU2016
from sim_vehicle.sensors.suite import SensorSuite, group_sigma, true_values
from sim_vehicle.state import TrueState


def trim_hold(duration_s: float = 120.0) -> str:
    """Calm air, trimmed default airframe, level flight: altitude and airspeed excursions."""
    rows = []
    for airframe in ("uav", "transport"):
        sim = Simulation(airframe, InitialCondition(), WindConfig(), ManoeuvreConfig(kind="level"))
        s0 = sim.state()
        n = round(duration_s / sim.dt_s)
        alt = np.empty(n)
        tas = np.empty(n)
        for k in range(n):
            s = sim.step()
            alt[k], tas[k] = s.alt_m, s.tas_mps
        rows.append([airframe, f"{duration_s:.0f}", f"{np.max(np.abs(alt - s0.alt_m)):.3f}",
                     f"{np.max(np.abs(tas - s0.tas_mps)):.3f}"])
    return md_table(["airframe", "duration [s]", "max |Δh| [m] (≤ 5)", "max |ΔV| [m/s] (≤ 1)"],
                    rows)


def dryden_psd_check(hours: float = 2.0, seed: int = 1) -> str:
    """Welch PSD of simulated Dryden turbulence against Lu2016 eqs. 21-23, 0.1-2 rad/s."""
    dt, tas, sigma, scale = 0.01, 25.0, 3.54, 530.0
    turb = DrydenTurbulence(sigma, scale, dt, np.random.default_rng(seed))
    n = int(hours * 3600 / dt)
    x = np.empty((n, 3))
    for k in range(n):
        x[k] = turb.step(tas)
    f_hz, p = signal.welch(x, fs=1 / dt, nperseg=2**16, axis=0)
    omega = 2 * math.pi * f_hz
    p_omega = p / (2 * math.pi)  # one-sided PSD per rad/s
    model = dryden_psd(omega, sigma, scale, tas)
    edges = np.geomspace(0.1, 2.0, 7)
    rows = []
    for lo, hi in zip(edges[:-1], edges[1:], strict=True):
        m = (omega >= lo) & (omega < hi)
        ratios = [float(np.mean(p_omega[m, i]) / np.mean(model[i][m])) for i in range(3)]
        rows.append([f"{lo:.2f}-{hi:.2f}"] + [f"{r:.2f}" for r in ratios])
    return md_table(["ω band [rad/s]", "Φ_u sim/eq.21", "Φ_v sim/eq.22", "Φ_w sim/eq.23"], rows) + \
        (f"\n\n({hours:g} h record at V = {tas} m/s, σ = {sigma} m/s, L = {scale} m; "
         "target ratio 0.7-1.3)")


def eq11_consistency() -> str:
    """Integrate Lu2016 eq. 11 (the monitor's GS-KM) with the noise-free simulated specific force
    and attitude, from the true velocity; worst velocity error against the simulation over 10 s."""
    cases = {
        "shear + turbulence": (WindConfig(kind="shear+turbulence", shear_start_s=12.0),
                               ManoeuvreConfig(kind="level"), 12.0),
        "parabolic": (WindConfig(), ManoeuvreConfig(kind="parabolic", start_s=3.0), 3.0),
        "coordinated turn": (WindConfig(), ManoeuvreConfig(kind="coordinated_turn", start_s=3.0),
                             3.0),
    }
    rows = []
    for name, (wind, man, t0) in cases.items():
        row = [name]
        for airframe in ("uav", "transport"):
            sim = Simulation(airframe, InitialCondition(lat_deg=60.0, heading_deg=45.0), wind,
                             man, seed=4)
            for _ in range(round(t0 / sim.dt_s)):
                sim.step()
            states = [sim.state()] + [sim.step() for _ in range(round(10.0 / sim.dt_s))]
            v = np.array(states[0].vel_ned_mps, dtype=float)
            err = 0.0
            for a, b in zip(states[:-1], states[1:], strict=True):
                dt = b.t_s - a.t_s

                def rate(vel: np.ndarray, s: object) -> np.ndarray:
                    x = np.concatenate((vel, s.euler_rad))  # type: ignore[attr-defined]
                    u = np.concatenate((s.acc_frd_mps2, s.omega_frd_radps))  # type: ignore[attr-defined]
                    return gs_km_f(x, u, s.lat_rad, s.alt_m)[:3]  # type: ignore[attr-defined]

                k1 = rate(v, a)
                k2 = rate(v + dt * k1, b)
                v = v + 0.5 * dt * (k1 + k2)
                err = max(err, float(np.max(np.abs(v - b.vel_ned_mps))))
            row.append(f"{err:.2e}")
        rows.append(row)
    return md_table(["case (60° N, 10 s)", "UAV max error [m/s]", "747 max error [m/s]"], rows) + \
        "\n\n(target ≤ 0.05 m/s)"


def sensor_noise(seconds: float = 60.0) -> str:
    """Measured noise std per sensor group against the tables (Lu2016 Table 1, Atmaca2025
    Table 1)."""
    st = TrueState(t_s=0.0, lat_rad=0.9, lon_rad=0.08, alt_m=1000.0,
                   vel_ned_mps=np.array([100.0, 5.0, -2.0]), euler_rad=np.array([0.1, 0.05, 1.0]),
                   omega_frd_radps=np.array([0.01, -0.02, 0.03]),
                   acc_frd_mps2=np.array([0.5, -0.1, -9.7]), wind_ned_mps=np.zeros(3),
                   tas_mps=100.0, aoa_rad=0.05, ssa_rad=0.01, pressure_alt_m=990.0,
                   static_pressure_pa=89_000.0, oat_k=281.7, cas_mps=95.0,
                   surf_cmd_rad=np.zeros(3), surf_pos_rad=np.zeros(3), rod_pos_m=np.zeros(3),
                   throttle=0.5)
    rows = []
    for sset in (LU2016, ATMACA2025):
        suite = SensorSuite(sset, n_imu=1, faults=(), seed=3)
        out: dict[str, list[np.ndarray]] = {}
        for k in range(round(seconds * 100)):
            for smp in suite.step(st, k * 10_000):
                out.setdefault(smp.group, []).append(np.asarray(smp.values, dtype=float))
        for group, vals in sorted(out.items()):
            if group.startswith(("aoa1", "aoa2", "cas1", "cas2")):
                continue
            err = np.array(vals) - true_values(group, st)
            expect = group_sigma(group, sset.noise, st.lat_rad)
            ok = expect > 0
            ratio = err.std(axis=0)[ok] / expect[ok]
            rows.append([sset.name, group, str(len(vals)),
                         f"{ratio.min():.3f}-{ratio.max():.3f}"])
    return md_table(["sensor set", "group", "samples", "measured σ / table σ (0.9-1.1)"], rows)


def sim_physics(out_dir: Path, jobs: int, quick: bool) -> str:
    """Checks of the simulator itself: trim hold, Dryden turbulence PSD, kinematic consistency
    with Lu2016 eq. 11 and the sensor noise levels."""
    parts = [
        "### Trim hold (calm air, level)\n\n" + trim_hold(30.0 if quick else 120.0),
        "### Dryden turbulence PSD\n\n" + dryden_psd_check(0.25 if quick else 2.0),
        "### Kinematic consistency with Lu2016 eq. 11\n\n" + eq11_consistency(),
        "### Sensor noise\n\n" + sensor_noise(10.0 if quick else 60.0),
    ]
    text = "\n\n".join(parts)
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "sim_physics.md").write_text(text + "\n")
    return text


def experiments() -> dict[str, Callable[[Path, int, bool], str]]:
    return {"sim_physics": sim_physics}
