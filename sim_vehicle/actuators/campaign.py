"""Seeded campaign of Lu2017's five actuator faults on every control surface (issue 17 item 4,
servo level): :func:`servo_campaign` turns ``(n_runs, seed)`` into a deterministic list of
:class:`~sim_vehicle.scenario.Scenario`\\ s.

Each run flies the transport in turbulence (Dryden, sigma 0.5-2.5 m/s, with or without a
shear) through one manoeuvre (3-2-1-1 on a random surface, S-turn, coordinated turn, climb or
level flight); a share of the runs is fault-free, the others carry one fault from t = 15-25 s
to the end, cycling through Lu2017's five cases on a surface drawn at random. Magnitudes are
ours (Lu2017 gives none): OFC amplitudes 0.03-0.1 of the valve command at 0.5-3 Hz, rod-sensor
biases of 5-30 mm (0.4-2.4 deg of surface), runaways in either direction.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gcs_monitor.core.atmosphere import tas_from_cas
from gcs_monitor.core.units import KT2MPS
from sim_vehicle.actuators.faults import SERVO_FAULT_KINDS, SURFACES, ActuatorFault
from sim_vehicle.scenario import (
    InitialSpec,
    ManoeuvreSpec,
    OutputConfig,
    Scenario,
    SensorConfig,
    WindSpec,
)

SERVO_MANOEUVRES = ("doublet_3211", "s_turn", "coordinated_turn", "climb", "level")
SERVO_WINDS = ("turbulence", "shear+turbulence")


@dataclass(frozen=True, slots=True)
class ServoRanges:
    """Draw ranges of :func:`servo_campaign` (uniform; random sign where a sign applies)."""

    duration_s: float = 40.0
    fault_start_s: tuple[float, float] = (15.0, 25.0)
    fault_free_share: float = 0.3
    cas_kts: tuple[float, float] = (200.0, 300.0)
    alt_m: tuple[float, float] = (1000.0, 6000.0)
    turbulence_sigma_mps: tuple[float, float] = (0.5, 2.5)
    ofc_amplitude: tuple[float, float] = (0.03, 0.1)  # valve-command units
    ofc_hz: tuple[float, float] = (0.5, 3.0)
    sensor_bias_m: tuple[float, float] = (0.005, 0.03)  # rod-sensor bias (liquid jam)


def _u(rng: np.random.Generator, lo_hi: tuple[float, float]) -> float:
    return float(rng.uniform(*lo_hi))


def servo_fault(rng: np.random.Generator, surface: int, kind: str, t0_s: float,
                r: ServoRanges = ServoRanges()) -> ActuatorFault:
    """One Lu2017 fault of ``kind`` on ``surface`` from ``t0_s`` to the end of the run."""
    sign = 1.0 if rng.random() < 0.5 else -1.0
    if kind in ("liquid_ofc", "solid_ofc"):
        return ActuatorFault(surface, kind, t0_s, None, round(_u(rng, r.ofc_amplitude), 4),
                             round(_u(rng, r.ofc_hz), 3),
                             round(float(rng.uniform(0.0, 2.0 * np.pi)), 3))
    if kind == "liquid_jam":
        return ActuatorFault(surface, kind, t0_s, None,
                             round(sign * _u(rng, r.sensor_bias_m), 4))
    if kind == "runaway":
        return ActuatorFault(surface, kind, t0_s, None, sign)
    if kind == "solid_jam":
        return ActuatorFault(surface, kind, t0_s)
    raise ValueError(f"unknown servo fault kind {kind!r}; expected one of {SERVO_FAULT_KINDS}")


def servo_campaign(n_runs: int, seed: int = 0, *,
                   ranges: ServoRanges = ServoRanges()) -> list[Scenario]:
    """Lu2017's five cases on every surface in turbulence, plus fault-free runs.

    Run ``i`` is fault-free when ``i`` falls on the fault-free share (evenly spread, so any
    prefix keeps the mix); the faulty runs cycle through Lu2017's five cases
    (:data:`SERVO_FAULT_KINDS`; every case is represented in small campaigns) on a surface
    drawn at random.
    """
    r = ranges
    rng = np.random.default_rng(np.random.SeedSequence([seed, 17]))
    out: list[Scenario] = []
    n_faulty = 0
    for i in range(n_runs):
        man = SERVO_MANOEUVRES[int(rng.integers(len(SERVO_MANOEUVRES)))]
        surf_man = SURFACES[int(rng.integers(len(SURFACES)))]
        wind_kind = SERVO_WINDS[int(rng.integers(len(SERVO_WINDS)))]
        fault_free = int((i + 1) * r.fault_free_share) > int(i * r.fault_free_share)
        faults: tuple[ActuatorFault, ...] = ()
        if not fault_free:
            kind = SERVO_FAULT_KINDS[n_faulty % len(SERVO_FAULT_KINDS)]
            n_faulty += 1
            surface = int(rng.integers(len(SURFACES)))
            t0 = round(_u(rng, r.fault_start_s), 2)
            faults = (servo_fault(rng, surface, kind, t0, r),)
        alt = float(round(_u(rng, r.alt_m), 0))
        tas = round(tas_from_cas(_u(rng, r.cas_kts) * KT2MPS, alt), 3)
        mean = tuple(float(round(x, 2)) for x in rng.uniform(-15.0, 15.0, 3) * [1, 1, 0.1])
        wind = WindSpec(kind=wind_kind, mean_ned_mps=mean,  # type: ignore[arg-type]
                        turbulence_sigma_mps=float(round(_u(rng, r.turbulence_sigma_mps), 2)),
                        shear_start_s=float(round(rng.uniform(10.0, r.duration_s / 2), 1)))
        desc = ("fault-free" if not faults else
                f"{SURFACES[faults[0].surface]} {faults[0].kind} at {faults[0].t_start_s:g} s")
        out.append(Scenario(
            name=f"servo_s{seed}_r{i:04d}",
            description=f"servo run {i} (seed {seed}): {desc}; {man} ({surf_man}), {wind_kind}",
            airframe="transport", duration_s=r.duration_s, seed=int(rng.integers(2**31)),
            dt_s=0.01,
            initial=InitialSpec(alt_m=alt, tas_mps=tas,
                                heading_deg=float(round(rng.uniform(0, 360), 1))),
            wind=wind,
            manoeuvre=ManoeuvreSpec(kind=man, start_s=5.0, surface=surf_man, repeat=True),
            sensors=SensorConfig(set_name="lu2016", n_imu=1), output=OutputConfig(),
            actuator_faults=faults, source="actuators.campaign.servo_campaign"))
    return out
