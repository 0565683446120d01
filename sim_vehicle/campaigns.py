"""Named campaign preset sets: seeded generators of :class:`~sim_vehicle.scenario.Scenario` lists.

A preset set turns ``(n_runs, seed)`` into a deterministic list of scenarios for the
evaluation harness (``gcs_monitor.evaluation.harness.run_campaign``):

* ``triplex`` -- single and double faults of the triplex AoA vanes and CAS probes (bias, drift,
  runaway, oscillation, jamming, noise) plus fault-free runs; transport airframe, 60-120 s,
  varied wind and manoeuvre (issue 3);
* ``wan2018`` -- Wan2018 sec. VI-B / Table II parametric runs (:mod:`sim_vehicle.wan2018_gen`);
* ``fault_free`` -- no fault, every manoeuvre in turbulence (threshold calibration and
  false-alarm checks);
* ``actuators`` -- the small UAV in manoeuvring flight with turbulence: a surface stuck at
  its position, stuck at zero or with lost effectiveness (aileron, elevator, rudder), the
  engine out, plus fault-free runs (issue 17);
* ``actuators_fault_free`` -- the same flights without faults (threshold calibration).

Magnitudes of the ``triplex`` set are ours (Wan2018 Table II ranges start at sizes the
monitor's thresholds see at once; these are chosen to sit between 1.5x and 6x the default
thresholds of 1 deg / 4 kt so detection delay and missed detections are informative).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from gcs_monitor.core.atmosphere import tas_from_cas
from gcs_monitor.core.units import DEG2RAD, KT2MPS
from sim_vehicle.actuators.faults import ACTUATORS, ENGINE, ActuatorFault
from sim_vehicle.faults.profiles import FaultSpec
from sim_vehicle.scenario import (
    MANOEUVRE_KINDS,
    InitialSpec,
    ManoeuvreSpec,
    OutputConfig,
    Scenario,
    SensorConfig,
    WindSpec,
)
from sim_vehicle.sensors.channels import N_AIRDATA

Generator = Callable[[int, int], list[Scenario]]


@dataclass(frozen=True, slots=True)
class TriplexRanges:
    """Draw ranges of the ``triplex`` set (uniform, random sign where a sign applies)."""

    cas_kts: tuple[float, float] = (180.0, 330.0)
    alt_m: tuple[float, float] = (1000.0, 9000.0)
    duration_s: tuple[float, float] = (60.0, 120.0)
    fault_start_s: tuple[float, float] = (15.0, 0.5)  # (earliest s, latest as duration share)
    fault_free_share: float = 0.3
    double_share: float = 0.3  # of the faulty runs
    aoa_bias_deg: tuple[float, float] = (2.0, 6.0)
    cas_bias_kts: tuple[float, float] = (8.0, 25.0)
    aoa_drift_degps: tuple[float, float] = (0.1, 0.5)
    cas_drift_ktsps: tuple[float, float] = (0.3, 1.5)
    aoa_drift_max_deg: float = 10.0
    cas_drift_max_kts: float = 40.0
    aoa_runaway_degps: tuple[float, float] = (1.0, 5.0)
    cas_runaway_ktsps: tuple[float, float] = (3.0, 10.0)
    aoa_runaway_limit_deg: float = 15.0
    cas_runaway_limit_kts: float = 60.0
    aoa_osc_deg: tuple[float, float] = (2.0, 5.0)
    cas_osc_kts: tuple[float, float] = (8.0, 20.0)
    osc_hz: tuple[float, float] = (0.5, 2.0)
    aoa_noise_deg: tuple[float, float] = (1.0, 2.0)
    cas_noise_kts: tuple[float, float] = (6.0, 15.0)
    turbulence_sigma_mps: tuple[float, float] = (0.5, 2.0)


TRIPLEX_KINDS = ("bias", "drift", "runaway", "oscillation", "jam", "noise")
TRIPLEX_MANOEUVRES = ("level", "doublet_3211", "coordinated_turn", "decel", "climb", "s_turn")
TRIPLEX_WINDS = ("calm", "constant", "turbulence", "shear+turbulence")


def _u(rng: np.random.Generator, lo_hi: tuple[float, float]) -> float:
    return float(rng.uniform(*lo_hi))


def _sign(rng: np.random.Generator) -> float:
    return 1.0 if rng.random() < 0.5 else -1.0


def triplex_fault(rng: np.random.Generator, channel: str, kind: str, t0_s: float,
                  r: TriplexRanges = TriplexRanges()) -> FaultSpec:
    """One fault of ``kind`` on an air-data channel (``aoa<i>`` or ``cas<i>``), SI parameters."""
    aoa = channel.startswith("aoa")
    u = "rad" if aoa else "mps"
    k = DEG2RAD if aoa else KT2MPS
    s = _sign(rng)
    p: tuple[tuple[str, object], ...]
    if kind == "bias":
        p = ((f"bias_{u}", s * _u(rng, r.aoa_bias_deg if aoa else r.cas_bias_kts) * k),)
    elif kind == "drift":
        rate = _u(rng, r.aoa_drift_degps if aoa else r.cas_drift_ktsps) * k
        cap = (r.aoa_drift_max_deg if aoa else r.cas_drift_max_kts) * k
        p = ((f"rate_{u}_per_s", s * rate), (f"max_{u}", cap))
    elif kind == "runaway":
        rate = _u(rng, r.aoa_runaway_degps if aoa else r.cas_runaway_ktsps) * k
        lim = (r.aoa_runaway_limit_deg if aoa else r.cas_runaway_limit_kts) * k
        p = ((f"rate_{u}_per_s", s * rate), (f"limit_{u}", lim))
    elif kind == "oscillation":
        amp = _u(rng, r.aoa_osc_deg if aoa else r.cas_osc_kts) * k
        p = ((f"amplitude_{u}", amp), ("frequency_hz", round(_u(rng, r.osc_hz), 3)))
    elif kind == "noise":
        p = ((f"sigma_{u}", _u(rng, r.aoa_noise_deg if aoa else r.cas_noise_kts) * k),)
    elif kind == "jam":
        p = ()
    else:
        raise ValueError(f"unknown triplex fault kind {kind!r}; expected one of {TRIPLEX_KINDS}")
    return FaultSpec(channel, kind, round(t0_s, 2), None, p)


def _transport(name: str, description: str, rng: np.random.Generator, duration_s: float,
               manoeuvre: str, wind_kind: str, faults: tuple[FaultSpec, ...],
               r: TriplexRanges, source: str) -> Scenario:
    alt = float(round(_u(rng, r.alt_m), 0))
    tas = round(tas_from_cas(_u(rng, r.cas_kts) * KT2MPS, alt), 3)
    mean = tuple(float(round(x, 2)) for x in rng.uniform(-15.0, 15.0, 3) * [1, 1, 0.1])
    wind = WindSpec(kind=wind_kind, mean_ned_mps=mean,  # type: ignore[arg-type]
                    turbulence_sigma_mps=float(round(_u(rng, r.turbulence_sigma_mps), 2)),
                    shear_start_s=float(round(rng.uniform(10.0, duration_s / 2), 1)))
    return Scenario(
        name=name, description=description, airframe="transport",
        duration_s=float(duration_s), seed=int(rng.integers(2**31)), dt_s=0.01,
        initial=InitialSpec(alt_m=alt, tas_mps=tas,
                            heading_deg=float(round(rng.uniform(0, 360), 1))),
        wind=wind, manoeuvre=ManoeuvreSpec(kind=manoeuvre, start_s=10.0, repeat=True),
        sensors=SensorConfig(), output=OutputConfig(), faults=faults, source=source,
    )


def triplex(n_runs: int, seed: int = 0, *,
            ranges: TriplexRanges = TriplexRanges()) -> list[Scenario]:
    """Single and double triplex AoA/CAS faults plus fault-free runs (issue 3).

    Run ``i`` is fault-free when ``i`` falls on the fault-free share (evenly spread, so any
    prefix of the list keeps the mix); a faulty run has one fault, or two (same set or one per
    set) with probability ``double_share``. Fault kinds cycle through :data:`TRIPLEX_KINDS`
    so every kind is represented in small campaigns.
    """
    r = ranges
    rng = np.random.default_rng(np.random.SeedSequence([seed, 3]))
    out: list[Scenario] = []
    n_faulty = 0
    for i in range(n_runs):
        duration = float(round(_u(rng, r.duration_s), 1))
        man = TRIPLEX_MANOEUVRES[int(rng.integers(len(TRIPLEX_MANOEUVRES)))]
        wind_kind = TRIPLEX_WINDS[int(rng.integers(len(TRIPLEX_WINDS)))]
        fault_free = int((i + 1) * r.fault_free_share) > int(i * r.fault_free_share)
        faults: tuple[FaultSpec, ...] = ()
        if not fault_free:
            kind = TRIPLEX_KINDS[n_faulty % len(TRIPLEX_KINDS)]
            n_faulty += 1
            t0 = _u(rng, (r.fault_start_s[0], r.fault_start_s[1] * duration))
            sets = ("aoa", "cas")
            first = f"{sets[int(rng.integers(2))]}{int(rng.integers(N_AIRDATA))}"
            chans = [first]
            if rng.random() < r.double_share:
                if rng.random() < 0.5:  # second fault in the same set
                    others = [f"{first[:3]}{k}" for k in range(N_AIRDATA)
                              if f"{first[:3]}{k}" != first]
                    chans.append(others[int(rng.integers(len(others)))])
                else:  # one per set
                    other = "cas" if first.startswith("aoa") else "aoa"
                    chans.append(f"{other}{int(rng.integers(N_AIRDATA))}")
            specs = []
            for j, ch in enumerate(sorted(chans)):
                k = kind if j == 0 else TRIPLEX_KINDS[int(rng.integers(len(TRIPLEX_KINDS)))]
                t = t0 if j == 0 else _u(rng, (t0, t0 + 10.0))
                specs.append(triplex_fault(rng, ch, k, t, r))
            faults = tuple(specs)
        desc = ("fault-free" if not faults else
                ", ".join(f"{f.channel} {f.kind} at {f.t_start_s:g} s" for f in faults))
        out.append(_transport(f"triplex_s{seed}_r{i:04d}",
                              f"triplex run {i} (seed {seed}): {desc}; {man}, {wind_kind}",
                              rng, duration, man, wind_kind, faults, r, "campaigns.triplex"))
    return out


def wan2018(n_runs: int, seed: int = 0) -> list[Scenario]:
    """Wan2018 sec. VI-B parametric runs (delegates to :func:`sim_vehicle.wan2018_gen.generate`)."""
    from sim_vehicle.wan2018_gen import generate

    return generate(n_runs, seed)


def fault_free(n_runs: int, seed: int = 0, *,
               ranges: TriplexRanges = TriplexRanges()) -> list[Scenario]:
    """No fault; manoeuvres cycle through every kind, wind is turbulence or shear+turbulence."""
    r = ranges
    rng = np.random.default_rng(np.random.SeedSequence([seed, 7]))
    winds = ("turbulence", "shear+turbulence")
    out = []
    for i in range(n_runs):
        man = MANOEUVRE_KINDS[i % len(MANOEUVRE_KINDS)]
        wind_kind = winds[(i // len(MANOEUVRE_KINDS)) % len(winds)]
        duration = float(round(_u(rng, r.duration_s), 1))
        out.append(_transport(f"fault_free_s{seed}_r{i:04d}",
                              f"fault-free run {i} (seed {seed}): {man}, {wind_kind}",
                              rng, duration, man, wind_kind, (), r, "campaigns.fault_free"))
    return out


@dataclass(frozen=True, slots=True)
class ActuatorRanges:
    """Draw ranges of the ``actuators`` set (uniform)."""

    duration_s: tuple[float, float] = (60.0, 80.0)
    fault_start_s: tuple[float, float] = (25.0, 40.0)
    fault_free_share: float = 0.3
    loss_of_effectiveness: tuple[float, float] = (0.5, 0.9)  # share of the effect lost
    turbulence_sigma_mps: tuple[float, float] = (0.5, 2.0)
    mean_wind_mps: float = 6.0  # horizontal steady wind up to this, random direction
    tas_mps: tuple[float, float] = (22.0, 28.0)
    alt_m: tuple[float, float] = (300.0, 1500.0)
    servo_hz: float = 50.0  # SERVO_OUTPUT_RAW rate (ArduPlane SRx_RC_CHAN = 50)


# (actuator, kind) of the ``actuators`` set, cycled so every case is in a small campaign
ACTUATOR_CASES: tuple[tuple[int, str], ...] = (
    *((s, k) for s in range(3) for k in ("solid_jam", "stuck_at_zero", "loss_of_effectiveness")),
    (ENGINE, "engine_out"),
)
# manoeuvring flight: every manoeuvre but level; doublets on each surface
ACTUATOR_MANOEUVRES: tuple[tuple[str, str], ...] = (
    ("s_turn", "elevator"), ("coordinated_turn", "elevator"), ("doublet_3211", "aileron"),
    ("doublet_3211", "elevator"), ("doublet_3211", "rudder"), ("climb", "elevator"),
    ("decel", "elevator"))


def _uav(name: str, description: str, rng: np.random.Generator, i: int,
         faults: tuple[ActuatorFault, ...], r: ActuatorRanges, source: str) -> Scenario:
    man, surface = ACTUATOR_MANOEUVRES[i % len(ACTUATOR_MANOEUVRES)]
    duration = float(round(_u(rng, r.duration_s), 1))
    ang = rng.uniform(0.0, 2.0 * np.pi)
    w = _u(rng, (0.0, r.mean_wind_mps))
    wind = WindSpec(kind="turbulence",
                    mean_ned_mps=(float(round(w * np.cos(ang), 2)),
                                  float(round(w * np.sin(ang), 2)), 0.0),
                    turbulence_sigma_mps=float(round(_u(rng, r.turbulence_sigma_mps), 2)))
    return Scenario(
        name=name, description=f"{description}; {man} ({surface}), sigma "
        f"{wind.turbulence_sigma_mps:g} m/s", airframe="uav", duration_s=duration,
        seed=int(rng.integers(2**31)), dt_s=0.01,
        initial=InitialSpec(alt_m=float(round(_u(rng, r.alt_m), 0)),
                            tas_mps=float(round(_u(rng, r.tas_mps), 2)),
                            heading_deg=float(round(rng.uniform(0, 360), 1))),
        wind=wind, manoeuvre=ManoeuvreSpec(kind=man, start_s=5.0, surface=surface, repeat=True),
        sensors=SensorConfig(n_imu=1), output=OutputConfig(servo_output_raw_hz=r.servo_hz),
        actuator_faults=faults, source=source)


def actuators(n_runs: int, seed: int = 0, *,
              ranges: ActuatorRanges = ActuatorRanges()) -> list[Scenario]:
    """Actuator faults of the small UAV in manoeuvring flight with turbulence (issue 17).

    Run ``i`` is fault-free when it falls on the fault-free share (evenly spread); a faulty run
    has one fault, the cases of :data:`ACTUATOR_CASES` taken in turn (stuck at position =
    Lu2017 solid jamming, stuck at zero, loss of effectiveness on each surface; the engine
    out). Manoeuvres cycle through :data:`ACTUATOR_MANOEUVRES`.
    """
    r = ranges
    rng = np.random.default_rng(np.random.SeedSequence([seed, 17]))
    out: list[Scenario] = []
    n_faulty = 0
    for i in range(n_runs):
        fault_free = int((i + 1) * r.fault_free_share) > int(i * r.fault_free_share)
        faults: tuple[ActuatorFault, ...] = ()
        t0 = float(round(_u(rng, r.fault_start_s), 2))
        if not fault_free:
            act, kind = ACTUATOR_CASES[n_faulty % len(ACTUATOR_CASES)]
            n_faulty += 1
            amp = (float(round(_u(rng, r.loss_of_effectiveness), 2))
                   if kind == "loss_of_effectiveness" else 0.0)
            faults = (ActuatorFault(act, kind, t0, None, amp),)
        desc = ("fault-free" if not faults else ", ".join(
            f"{ACTUATORS[f.surface]} {f.kind}" + (f" {f.amplitude:g}" if f.amplitude else "")
            + f" at {f.t_start_s:g} s" for f in faults))
        out.append(_uav(f"actuators_s{seed}_r{i:04d}", f"actuator run {i} (seed {seed}): {desc}",
                        rng, i, faults, r, "campaigns.actuators"))
    return out


def actuators_fault_free(n_runs: int, seed: int = 0, *,
                         ranges: ActuatorRanges = ActuatorRanges()) -> list[Scenario]:
    """The ``actuators`` flights without faults (threshold calibration, false alarms)."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, 18]))
    out = []
    for i in range(n_runs):
        _u(rng, ranges.fault_start_s)  # same draw sequence as ``actuators``
        out.append(_uav(f"actuators_ff_s{seed}_r{i:04d}",
                        f"fault-free actuator-family run {i} (seed {seed})", rng, i, (),
                        ranges, "campaigns.actuators_fault_free"))
    return out


PRESET_SETS: dict[str, tuple[Generator, str]] = {
    "triplex": (triplex, "single/double triplex AoA and CAS faults (6 kinds) + fault-free runs, "
                         "transport, 60-120 s"),
    "wan2018": (wan2018, "Wan2018 sec. VI-B / Table II parametric runs, 60-700 s"),
    "fault_free": (fault_free, "no fault, every manoeuvre, turbulence (threshold calibration)"),
    "actuators": (actuators, "small UAV, manoeuvring in turbulence: each surface stuck, stuck at "
                             "zero or lost effectiveness, engine out, + fault-free runs"),
    "actuators_fault_free": (actuators_fault_free, "the actuators set's flights without faults"),
}


def list_preset_sets() -> list[tuple[str, str]]:
    """(name, description) of every preset set."""
    return [(k, v[1]) for k, v in PRESET_SETS.items()]


def generate_set(name: str, n_runs: int, seed: int = 0) -> list[Scenario]:
    """The scenarios of preset set ``name``; deterministic for ``(n_runs, seed)``."""
    try:
        gen = PRESET_SETS[name][0]
    except KeyError:
        raise ValueError(f"unknown preset set {name!r}; expected one of "
                         f"{sorted(PRESET_SETS)}") from None
    if n_runs < 1:
        raise ValueError(f"n_runs must be >= 1, got {n_runs}")
    return gen(n_runs, seed)
