"""Wan2018 on real data: the OnSpeed light aircraft, deceleration to the stall.

The flight has one AoA vane and one IAS sensor; three synthetic instances per set are built from
each (the real signal plus noise of the sensor's own measured level, different seeds), Table II
faults are added open loop to 0-3 of them (:func:`~gcs_monitor.evaluation.scenarios.\
onspeed_fault_cases`), the result is written as a contract tlog and replayed through the
:class:`~gcs_monitor.monitor.Monitor` with the CMHE tuned for a light aircraft
(:func:`~gcs_monitor.evaluation.configs.light_aircraft_estimator`). Scores: detection, isolation and
the estimate's error against the real sensor. The data folder is
:func:`gcs_monitor.evaluation.data.real_data_dir` (``--data-dir``, ``GCS_DATA_DIR``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from gcs_monitor.config import MonitorConfig
from gcs_monitor.convert.encode import TlogEncoder
from gcs_monitor.convert.formats import Flight, read_onspeed
from gcs_monitor.core.atmosphere import isa_temperature_k
from gcs_monitor.core.types import ChannelId
from gcs_monitor.core.units import DEG2RAD, KT2MPS
from gcs_monitor.evaluation.configs import (
    airdata_of,
    light_aircraft_estimator,
    variant_config,
    with_thresholds,
)
from gcs_monitor.evaluation.data import real_data_file
from gcs_monitor.evaluation.report import fmt_fixed, md_table, pyplot, write_csv
from gcs_monitor.evaluation.runner import run_parallel
from gcs_monitor.evaluation.runs import replay_tlog
from gcs_monitor.evaluation.scenarios import onspeed_fault_cases
from gcs_monitor.fdi.events import AlarmEvent, AlarmKind, AlarmState
from sim_vehicle.faults.profiles import FaultInjector, FaultSpec

ONSPEED_FILE = "onspeed_vac_decel_stall_50hz.csv"  # in the real-data folder
ONSPEED_NOISE_WINDOW_N = 11  # centred moving average used to measure the sensor noise
ONSPEED_SEEDS = (11, 12, 13)  # noise of the three synthetic instances (evaluation)
ONSPEED_CAL_SEEDS = (101, 102, 103, 104, 105)  # separate noise draws for the thresholds
# The stall break at ~17.5 s (roll to -46 deg, 0.27 g) leaves the wings-level longitudinal
# model of Wan2018 (eqs. 1-16): the replay ends before it (J of the clean AoA reaches 6.9 deg
# during the break and recovery, see docs/results-airdata.md).
ONSPEED_END_S = 17.0


def truncate_flight(flight: Flight, t_end_s: float) -> Flight:
    """The flight up to ``t_end_s`` (every time-indexed array cut)."""
    k = flight.t_s <= t_end_s
    g = flight.gps_t_s <= t_end_s
    a = flight.air_t_s <= t_end_s
    cut = {n: getattr(flight, n)[a] for n in ("cas_mps", "aoa_rad", "baro_alt_m", "climb_mps",
                                              "static_pressure_pa", "oat_k")
           if len(getattr(flight, n)) == len(flight.air_t_s)}
    return dataclasses.replace(
        flight, t_s=flight.t_s[k], acc_frd_mps2=[x[k] for x in flight.acc_frd_mps2],
        omega_frd_radps=[x[k] for x in flight.omega_frd_radps], euler_rad=flight.euler_rad[k],
        gps_t_s=flight.gps_t_s[g], gps_vel_ned_mps=flight.gps_vel_ned_mps[g],
        lat_rad=flight.lat_rad[g], lon_rad=flight.lon_rad[g], alt_m=flight.alt_m[g],
        air_t_s=flight.air_t_s[a], **cut)


def measured_noise(x: np.ndarray, n: int = ONSPEED_NOISE_WINDOW_N) -> float:
    """1-sigma noise of a sensor signal: std of ``x - centred moving average(x, n)``, scaled by
    ``sqrt(n / (n - 1))`` (the average contains the sample itself). Slow flight dynamics
    (the 30 s deceleration) pass the n-sample average; the sample-to-sample noise does not."""
    k = np.ones(n) / n
    ma = np.convolve(x, k, mode="same")
    h = n // 2
    d = (x - ma)[h:-h]
    return float(np.std(d) * math.sqrt(n / (n - 1)))


def _apply_faults(t_s: np.ndarray, true_val: np.ndarray, y: np.ndarray, channel: str,
                  faults: Sequence[FaultSpec]) -> np.ndarray:
    """Open-loop injection with the simulator's fault profiles (sim_vehicle.faults)."""
    inj = FaultInjector(tuple(f for f in faults if f.channel == channel))
    if channel not in inj.channels:
        return y
    return np.array([inj.apply(channel, float(t), float(x), float(h))
                     for t, x, h in zip(t_s, true_val, y, strict=True)])


def write_triplex_tlog(flight: Flight, out: Path, aoa3: np.ndarray, cas3: np.ndarray) -> Path:
    """Encode a Flight with triplex air data: AIRSPEED ids 0-2, AOA_SSA + NAMED_VALUE_FLOAT
    AOA1/AOA2 (docs/telemetry.md), IMU/attitude/GPS/VFR_HUD as ``convert.writer``."""
    f = flight
    gps_i = 0
    next_hb = 0.0
    with TlogEncoder(out) as enc:
        for k in range(len(f.t_s)):
            tk = float(f.t_s[k])
            t_us = int(round(tk * 1e6))
            if tk >= next_hb:
                enc.heartbeat(t_us)
                next_hb += 1.0
            while gps_i < len(f.gps_t_s) and f.gps_t_s[gps_i] <= tk + 1e-9:
                v = f.gps_vel_ned_mps[gps_i]
                enc.gps(int(round(float(f.gps_t_s[gps_i]) * 1e6)), float(f.lat_rad[gps_i]),
                        float(f.lon_rad[gps_i]), float(f.alt_m[gps_i]),
                        (float(v[0]), float(v[1]), float(v[2])))
                gps_i += 1
            enc.imu(t_us, 0, tuple(f.acc_frd_mps2[0][k]), tuple(f.omega_frd_radps[0][k]))
            e = f.euler_rad[k]
            enc.attitude(t_us, (float(e[0]), float(e[1]), float(e[2])))
            oat = float(f.oat_k[k]) if len(f.oat_k) else isa_temperature_k(float(f.baro_alt_m[k]))
            for i in range(3):
                enc.airspeed(t_us, i, float(cas3[k, i]), oat)
            enc.aoa(t_us, [float(a) for a in aoa3[k]], 0.0)
            enc.vfr_hud(t_us, cas_mps=float(cas3[k, 0]), groundspeed_mps=0.0, heading_rad=0.0,
                        baro_alt_m=float(f.baro_alt_m[k]), climb_mps=float(f.climb_mps[k]))
    return out


def _noisy_triplex(x: np.ndarray, sigma: float, seeds: Sequence[int]) -> np.ndarray:
    return np.column_stack([x + np.random.default_rng(sd).normal(0.0, sigma, x.shape)
                            for sd in seeds])


OnspeedCase = tuple[Flight, tuple[FaultSpec, ...], Sequence[int], dict[str, float], Path,
                    MonitorConfig]


def _onspeed_case(job: OnspeedCase) -> tuple[list[AlarmEvent], dict[str, np.ndarray]]:
    """Three noisy instances per set with ``faults``, written to a tlog at ``path``, replayed."""
    flight, faults, seeds, sig, path, cfg = job
    t = flight.t_s
    aoa3 = _noisy_triplex(flight.aoa_rad, sig["aoa"], seeds)
    cas3 = _noisy_triplex(flight.cas_mps, sig["cas"], [sd + 1000 for sd in seeds])
    for i in range(3):
        aoa3[:, i] = _apply_faults(t, flight.aoa_rad, aoa3[:, i], f"aoa{i}", faults)
        cas3[:, i] = _apply_faults(t, flight.cas_mps, cas3[:, i], f"cas{i}", faults)
    write_triplex_tlog(flight, path, aoa3, cas3)
    return replay_tlog(path, cfg, light_aircraft_estimator)


def _case_row(name: str, faults: Sequence[FaultSpec], ev: Sequence[AlarmEvent],
              ser: dict[str, np.ndarray], flight: Flight) -> list[str | int]:
    """Detection, delay, false isolation and estimation error of one replayed case."""
    truth = {"aoa": flight.aoa_rad, "cas": flight.cas_mps}
    raised = [e for e in ev if e.state is AlarmState.RAISED and e.kind is AlarmKind.SENSOR_FAULT]
    fch = {f.channel: f.t_start_s for f in faults}
    det, delays, wrong = 0, [], []
    for ch, t0 in fch.items():
        cid = ChannelId(ch[:3], int(ch[3:]))
        hit = [e.t_us * 1e-6 for e in raised if e.channel == cid and e.t_us * 1e-6 >= t0]
        if hit:
            det += 1
            delays.append(min(hit) - t0)
    for e in raised:
        c = f"{e.channel.kind}{e.channel.instance}"
        if c not in fch or e.t_us * 1e-6 < fch[c]:
            wrong.append(c)
    err = {}
    settled = ser["t"] >= 3.0
    for s in ("aoa", "cas"):
        tr = np.interp(ser["t"], flight.air_t_s, truth[s])
        e = np.abs(ser[f"{s}_est"] - tr)[settled]
        e = e[np.isfinite(e)]
        err[s] = (float(np.sqrt(np.mean(e * e))) if e.size else math.nan,
                  float(e.max()) if e.size else math.nan)
    return [name, len(fch), det, fmt_fixed(max(delays)) if delays else "-",
            ",".join(sorted(set(wrong))) or "none",
            fmt_fixed(err["aoa"][0] / DEG2RAD, 3), fmt_fixed(err["aoa"][1] / DEG2RAD, 3),
            fmt_fixed(err["cas"][0] / KT2MPS, 3), fmt_fixed(err["cas"][1] / KT2MPS, 3)]


def _plot_case(flight: Flight, ser: dict[str, np.ndarray], name: str, path: Path) -> None:
    truth = {"aoa": flight.aoa_rad, "cas": flight.cas_mps}
    plt = pyplot()
    fig, axs = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
    for a, s, unit, fac in ((axs[0], "aoa", "deg", DEG2RAD), (axs[1], "cas", "kt", KT2MPS)):
        a.plot(flight.air_t_s, truth[s] / fac, "k", lw=1, label="real sensor")
        a.plot(ser["t"], ser[f"{s}_est"] / fac, "r", lw=1, label="CMHE estimate")
        a.set_ylabel(f"{s.upper()} [{unit}]")
        a.grid(alpha=0.3)
    axs[0].legend()
    axs[1].set_xlabel("t [s]")
    fig.suptitle(f"OnSpeed decel to stall, case {name}")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def wan2018_onspeed(out_dir: Path, jobs: int, quick: bool, data_dir: Path) -> str:
    """Real OnSpeed flight (46-75 kts, to the stall) with three synthetic instances per set
    built from the one real AoA and IAS sensor; Table II faults on 0-3 instances, replayed
    through the tlog path; detection, isolation and estimation error against the real sensor."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    flight = truncate_flight(read_onspeed(real_data_file(data_dir, ONSPEED_FILE)), ONSPEED_END_S)
    sig = {"aoa": measured_noise(flight.aoa_rad), "cas": measured_noise(flight.cas_mps)}
    base = variant_config("cmhe")
    # thresholds: 1.5 x the worst J of the clean flight over separate noise seeds
    cal_seeds = ONSPEED_CAL_SEEDS[:2] if quick else ONSPEED_CAL_SEEDS
    cal: list[OnspeedCase] = [(flight, (), (sd, sd + 10, sd + 20), sig,
                               out / f"onspeed_cal{k}.tlog", base)
                              for k, sd in enumerate(cal_seeds)]
    jmax = {"aoa": 0.0, "cas": 0.0}
    for _, ser in run_parallel(_onspeed_case, cal, jobs, desc="onspeed calibrate"):
        for s in jmax:
            jmax[s] = max(jmax[s], float(np.nanmax(ser[f"{s}_j"])))
    cfg = with_thresholds(base, 1.5 * jmax["aoa"], 1.5 * jmax["cas"])
    cases = onspeed_fault_cases()
    work: list[OnspeedCase] = [(flight, faults, ONSPEED_SEEDS, sig, out / f"onspeed_{name}.tlog",
                                cfg) for name, faults in cases.items()]
    rows = []
    for (name, faults), (ev, ser) in zip(
            cases.items(), run_parallel(_onspeed_case, work, jobs, desc="onspeed"), strict=True):
        rows.append(_case_row(name, faults, ev, ser, flight))
        if name in ("clean", "three"):
            _plot_case(flight, ser, name, out / f"wan2018_onspeed_{name}.png")
    hdr = ["case", "faulty instances", "detected", "delay max [s]", "false isolation",
           "AoA err RMS [deg]", "AoA err max [deg]", "IAS err RMS [kt]", "IAS err max [kt]"]
    write_csv(out / "wan2018_onspeed.csv", hdr, rows)
    fdi = airdata_of(cfg).fdi
    head = (f"Measured noise (std of x - 11-sample centred mean): AoA {sig['aoa'] / DEG2RAD:.3f} "
            f"deg, IAS {sig['cas'] / KT2MPS:.3f} kt. Thresholds (1.5 x worst J of the clean "
            f"flight over {len(cal_seeds)} other noise seeds): AoA "
            f"{fdi.aoa.threshold / DEG2RAD:.3f} deg, IAS {fdi.cas.threshold / KT2MPS:.2f} kt."
            "\n\n")
    return head + md_table(hdr, rows)


def real_data_experiments() -> dict[str, Callable[[Path, int, bool, Path], str]]:
    """Named experiments on the real data (registry hook)."""
    return {"wan2018_onspeed": wan2018_onspeed}
