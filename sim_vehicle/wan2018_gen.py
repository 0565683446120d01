"""Seeded random parametric runs after Wan2018 sec. VI-B and Table II.

Each run: the transport airframe across the envelope (CAS 160-360 kts, duration 60-700 s), one
of several manoeuvres and wind profiles, and either no fault or one to three faulty sensors among
the triplex AoA vanes and/or CAS probes, each with a fault family and magnitude drawn from
Wan2018 Table II. Deterministic for a seed.

Wan2018 gives ranges, not a distribution; we draw uniformly within each range and a random
sign. Flight conditions are given as CAS; the initial TAS is converted at the drawn altitude.

Run counts follow Wan2018 sec. VI-B exactly in proportion: 140 of 249 runs fault-free, and the
109 faulty runs split over the output configurations of Table I as 47 / 22 / 25 / 15:
I (some but not all AoA and/or CAS instances faulty), II (all three AoA vanes faulty, plus 0-2
CAS), III (all three CAS probes, plus 0-2 AoA), IV (all six). Counts are rounded for other
``n_runs`` and the categories are shuffled over the runs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gcs_monitor.core.atmosphere import tas_from_cas
from gcs_monitor.core.units import DEG2RAD, KT2MPS
from sim_vehicle.faults.profiles import FaultSpec
from sim_vehicle.scenario import (
    InitialSpec,
    ManoeuvreSpec,
    OutputConfig,
    Scenario,
    SensorConfig,
    WindSpec,
)
from sim_vehicle.sensors.channels import N_AIRDATA


@dataclass(frozen=True, slots=True)
class Wan2018Ranges:
    """Wan2018 Table II (AOA | VCAS) and sec. VI-B envelope."""

    cas_kts: tuple[float, float] = (160.0, 360.0)
    duration_s: tuple[float, float] = (60.0, 700.0)
    alt_m: tuple[float, float] = (1000.0, 9000.0)  # ours: Wan2018 gives no altitude range
    aoa_amp_deg: tuple[float, float] = (0.5, 25.0)  # oscillation, jamming offset, bias
    cas_amp_kts: tuple[float, float] = (10.0, 200.0)
    aoa_osc_hz: tuple[float, float] = (0.5, 1.0)
    cas_osc_hz: tuple[float, float] = (0.5, 4.0)
    aoa_runaway_degps: tuple[float, float] = (0.2, 25.0)
    cas_runaway_ktsps: tuple[float, float] = (0.5, 50.0)
    nrz_level: float = 0.1  # "10% x current value": the output falls to 10 % of the value
    nrz_gain: float | None = None  # the literal additive reading f = gain x instead (0.1)
    aoa_noise_deg: tuple[float, float] = (1.0, 2.0)
    cas_noise_kts: tuple[float, float] = (10.0, 20.0)
    fault_free_fraction: float = 140.0 / 249.0  # 140 fault-free of 249 runs
    category_counts: tuple[int, int, int, int] = (47, 22, 25, 15)  # Table I I-IV, faulty runs


FAMILIES = ("oscillation", "jam", "bias", "runaway", "nrz", "noise")
MANOEUVRES = ("level", "doublet_3211", "coordinated_turn", "decel", "climb", "s_turn")
WINDS = ("calm", "constant", "shear", "turbulence", "shear+turbulence")


def _fault(rng: np.random.Generator, r: Wan2018Ranges, channel: str, t0: float) -> FaultSpec:
    aoa = channel.startswith("aoa")
    fam = FAMILIES[int(rng.integers(len(FAMILIES)))]
    sign = 1.0 if rng.random() < 0.5 else -1.0
    amp = (rng.uniform(*r.aoa_amp_deg) * DEG2RAD if aoa else rng.uniform(*r.cas_amp_kts) * KT2MPS)
    u = "rad" if aoa else "mps"
    if fam == "oscillation":
        f = rng.uniform(*(r.aoa_osc_hz if aoa else r.cas_osc_hz))
        p: tuple[tuple[str, object], ...] = ((f"amplitude_{u}", amp), ("frequency_hz", f))
    elif fam == "bias":
        p = ((f"bias_{u}", sign * amp),)
    elif fam == "runaway":
        rate = (rng.uniform(*r.aoa_runaway_degps) * DEG2RAD if aoa
                else rng.uniform(*r.cas_runaway_ktsps) * KT2MPS)
        # limit: the top of the Table II amplitude range (ours: Table II gives only the rate)
        lim = r.aoa_amp_deg[1] * DEG2RAD if aoa else r.cas_amp_kts[1] * KT2MPS
        p = ((f"rate_{u}_per_s", sign * rate), (f"limit_{u}", lim))
    elif fam == "nrz":
        p = (("level", r.nrz_level),) if r.nrz_gain is None else (("gain", r.nrz_gain),)
    elif fam == "noise":
        sig = (rng.uniform(*r.aoa_noise_deg) * DEG2RAD if aoa
               else rng.uniform(*r.cas_noise_kts) * KT2MPS)
        p = ((f"sigma_{u}", sig),)
    else:  # jam: stuck at the value at fault start
        p = ()
    return FaultSpec(channel, fam, round(t0, 2), None, p)


CATEGORIES = ("none", "I", "II", "III", "IV")


def category_plan(n_runs: int, r: Wan2018Ranges) -> list[str]:
    """Category per run before shuffling: rounded Wan2018 proportions, summing to ``n_runs``."""
    n_free = int(round(n_runs * r.fault_free_fraction))
    n_faulty = n_runs - n_free
    tot = sum(r.category_counts)
    exact = [n_faulty * c / tot for c in r.category_counts]
    counts = [int(np.floor(x)) for x in exact]
    short = n_faulty - sum(counts)
    for k in np.argsort([c - x for c, x in zip(counts, exact, strict=True)])[:short]:
        counts[int(k)] += 1
    plan = ["none"] * n_free
    for name, c in zip(CATEGORIES[1:], counts, strict=True):
        plan += [name] * c
    return plan


def _category_channels(rng: np.random.Generator, cat: str) -> list[str]:
    """Faulty channels of a run of Table I category ``cat``."""
    aoa = [f"aoa{k}" for k in range(N_AIRDATA)]
    cas = [f"cas{k}" for k in range(N_AIRDATA)]
    if cat == "IV":
        return aoa + cas
    if cat in ("II", "III"):
        full, other = (aoa, cas) if cat == "II" else (cas, aoa)
        k = int(rng.integers(0, N_AIRDATA))  # 0-2 instances of the other set
        return full + [str(c) for c in rng.choice(other, size=k, replace=False)]
    # I: 1-2 of one set, or 1-2 of each, never a whole set
    n_a, n_c = 0, 0
    while n_a + n_c == 0:
        n_a, n_c = int(rng.integers(0, N_AIRDATA)), int(rng.integers(0, N_AIRDATA))
    return ([str(c) for c in rng.choice(aoa, size=n_a, replace=False)]
            + [str(c) for c in rng.choice(cas, size=n_c, replace=False)])


def generate(n_runs: int, seed: int = 0, *, ranges: Wan2018Ranges = Wan2018Ranges(),
             airframe: str = "transport") -> list[Scenario]:
    """``n_runs`` random scenarios, deterministic for ``seed`` (see :func:`category_plan`)."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, 2018]))
    plan = category_plan(n_runs, ranges)
    rng.shuffle(plan)
    out = []
    for i in range(n_runs):
        r = ranges
        duration = float(round(rng.uniform(*r.duration_s), 1))
        alt = float(round(rng.uniform(*r.alt_m), 0))
        cas = float(rng.uniform(*r.cas_kts)) * KT2MPS
        tas = round(tas_from_cas(cas, alt), 3)
        man = MANOEUVRES[int(rng.integers(len(MANOEUVRES)))]
        wind_kind = WINDS[int(rng.integers(len(WINDS)))]
        mean = tuple(float(round(x, 2)) for x in rng.uniform(-15.0, 15.0, 3) * [1, 1, 0.1])
        wind = WindSpec(kind=wind_kind, mean_ned_mps=mean,  # type: ignore[arg-type]
                        turbulence_sigma_mps=float(round(rng.uniform(0.5, 3.54), 2)),
                        shear_start_s=float(round(rng.uniform(10.0, duration / 2), 1)))
        faults: tuple[FaultSpec, ...] = ()
        if plan[i] != "none":
            chans = _category_channels(rng, plan[i])
            faults = tuple(
                _fault(rng, r, str(c), float(rng.uniform(10.0, 0.6 * duration)))
                for c in sorted(chans)
            )
        out.append(Scenario(
            name=f"wan2018_s{seed}_r{i:04d}",
            description=f"Wan2018 Table II parametric run {i} (seed {seed}), category "
                        f"{plan[i]}, {len(faults)} faulty air-data sensor(s)",
            airframe=airframe,
            duration_s=duration,
            seed=int(rng.integers(2**31)),
            dt_s=0.01,
            initial=InitialSpec(alt_m=alt, tas_mps=tas,
                                heading_deg=float(round(rng.uniform(0, 360), 1))),
            wind=wind,
            manoeuvre=ManoeuvreSpec(kind=man, start_s=10.0, repeat=True),
            sensors=SensorConfig(),
            output=OutputConfig(),
            faults=faults,
            source="wan2018_gen",
        ))
    return out
