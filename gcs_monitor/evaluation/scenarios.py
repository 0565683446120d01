"""The scenarios the experiments fly: preset sets, the papers' set-ups and their variants.

Every list here is deterministic for its arguments (seeds included), so an experiment can be
re-run and compared. Scenarios are built in memory from the simulator's presets and generators
(``sim_vehicle.scenario``, ``sim_vehicle.campaigns``, ``sim_vehicle.wan2018_gen``).
"""

from __future__ import annotations

import dataclasses

from gcs_monitor.core.atmosphere import tas_from_cas
from gcs_monitor.core.units import DEG2RAD, KT2MPS
from sim_vehicle.campaigns import generate_set
from sim_vehicle.faults.profiles import FaultSpec
from sim_vehicle.scenario import (
    InitialSpec,
    ManoeuvreSpec,
    OutputConfig,
    Scenario,
    SensorConfig,
    WindSpec,
    load_scenario,
    with_overrides,
)
from sim_vehicle.wan2018_gen import Wan2018Ranges, generate

# Wan2018 sec. VI-A figures: transport at 350 kts CAS, 5000 ft
ALT_FIG_M = 1524.0  # 5000 ft (Wan2018 sec. VI-A)
CAS_FIG_KTS = 350.0  # Wan2018 sec. VI-A
FIG45_T0_S = 20.0  # start of the three runaways of Figs. 4-5
# Wan2018 sec. VI-B campaign
CAMPAIGN_SEED = 0
CALIBRATION_SEED = 1000  # fault-free calibration runs, separate from the evaluation seeds
FULL_DURATION_S = (60.0, 700.0)  # Wan2018 sec. VI-B: 60-700 s
SCHEDULE_CALM_RUNS = 120  # fault-free runs of seed CALIBRATION_SEED + 1 drawn for the calm floor
SCHEDULE_CALM_DURATION_S = (60.0, 200.0)  # several s-turn / doublet cycles each
NRZ_LITERAL_GAIN = 0.1  # Table II's "10 % x current value" read as an additive f = 0.1 x


def preset_set(name: str, runs: int, seed: int = 0) -> list[Scenario]:
    """``runs`` scenarios of a preset set (:func:`sim_vehicle.campaigns.list_preset_sets`);
    the list is deterministic for ``(runs, seed)`` and a shorter one is its prefix."""
    return generate_set(name, runs, seed)


# ------------------------------------------------------------------------------------------------
# Wan2018
# ------------------------------------------------------------------------------------------------


def wind_scenarios() -> dict[str, WindSpec]:
    """Three wind scenarios of growing size (Wan2018 Fig. 2 is not in the text; ours:
    1 light turbulence with a steady wind, 2 shear of 10 m/s + moderate turbulence, 3 a 22 m/s
    head wind + 25 m/s shear + severe turbulence, beyond the bounds assumed for scenario 2
    (Fig. 3))."""
    return {
        "1": WindSpec(kind="turbulence", mean_ned_mps=(8.0, 4.0, 0.0), turbulence_sigma_mps=1.0),
        "2": WindSpec(kind="shear+turbulence", mean_ned_mps=(12.0, 6.0, 0.0),
                      turbulence_sigma_mps=2.0, shear_start_s=15.0, shear_amplitude_mps=10.0),
        # head wind (the runs fly north): the 25 m/s shear outflow adds to the steady 20 m/s,
        # the along-heading wind reaches ~45 m/s + gusts, beyond scenario 2's envelope
        "3": WindSpec(kind="shear+turbulence", mean_ned_mps=(-20.0, -10.0, 0.0),
                      turbulence_sigma_mps=3.54, shear_start_s=15.0, shear_amplitude_mps=25.0),
    }


def fig_scenario(name: str, wind: WindSpec, duration_s: float,
                 faults: tuple[FaultSpec, ...] = (), seed: int = 7) -> Scenario:
    """Transport at 350 kts CAS, 5000 ft, repeated 3-2-1-1 elevator doublets (Wan2018 VI-A)."""
    tas = tas_from_cas(CAS_FIG_KTS * KT2MPS, ALT_FIG_M)
    return Scenario(name=name, description=name, airframe="transport", duration_s=duration_s,
                    seed=seed, dt_s=0.01, initial=InitialSpec(alt_m=ALT_FIG_M, tas_mps=tas),
                    wind=wind, manoeuvre=ManoeuvreSpec(kind="doublet_3211", start_s=10.0,
                                                       repeat=True),
                    sensors=SensorConfig(), output=OutputConfig(), faults=faults,
                    source="wan2018_eval")


def runaway_faults(rate_ktsps: float, t0_s: float = FIG45_T0_S) -> tuple[FaultSpec, ...]:
    """Three simultaneous CAS runaways (Wan2018 Fig. 4), limit 200 kts (Table II top)."""
    return tuple(FaultSpec(f"cas{i}", "runaway", t0_s, None,
                           (("rate_mps_per_s", -rate_ktsps * KT2MPS),
                            ("limit_mps", 200.0 * KT2MPS))) for i in range(3))


def campaign_scenarios(n_runs: int, seed: int, duration_s: tuple[float, float],
                       fault_free_only: bool = False,
                       nrz_gain: float | None = None) -> list[Scenario]:
    """The seeded campaign runs. Table II's non-return to zero is the output falling to 10 % of
    the value (``y = 0.1 x``; docs/papers-notes.md); ``nrz_gain`` injects the literal additive
    reading ``f = nrz_gain x`` instead. It draws no random number, so every run stays the same
    otherwise."""
    r = Wan2018Ranges(duration_s=duration_s)
    if nrz_gain is not None:
        r = dataclasses.replace(r, nrz_gain=nrz_gain)
    if fault_free_only:
        r = dataclasses.replace(r, fault_free_fraction=1.0)
    return generate(n_runs, seed, ranges=r)


def calm_calibration_scenarios(n_runs: int = SCHEDULE_CALM_RUNS) -> list[Scenario]:
    """Extra fault-free runs for the calm end of the threshold schedule: the non-turbulent ones
    among ``n_runs`` draws of the campaign generator (seed ``CALIBRATION_SEED + 1``, durations
    ``SCHEDULE_CALM_DURATION_S``), so that every manoeuvre is seen in calm air several times."""
    scs = campaign_scenarios(n_runs, CALIBRATION_SEED + 1, SCHEDULE_CALM_DURATION_S,
                             fault_free_only=True)
    return [sc for sc in scs if "turbulence" not in sc.wind.kind]


def onspeed_fault_cases() -> dict[str, tuple[FaultSpec, ...]]:
    """Open-loop Table II faults on 0-3 of the synthetic instances of each set (the OnSpeed
    replay: three instances built from the one real AoA and IAS sensor)."""
    b = 3.0 * DEG2RAD
    return {
        "clean": (),
        "one": (FaultSpec("aoa1", "bias", 8.0, None, (("bias_rad", b),)),
                FaultSpec("cas0", "runaway", 10.0, None, (("rate_mps_per_s", -5.0 * KT2MPS),
                                                         ("limit_mps", 20.0 * KT2MPS)))),
        "two": (FaultSpec("aoa0", "jam", 8.0, None, ()),
                FaultSpec("aoa2", "bias", 12.0, None, (("bias_rad", -b),)),
                FaultSpec("cas1", "bias", 10.0, None, (("bias_mps", 10.0 * KT2MPS),)),
                FaultSpec("cas2", "oscillation", 10.0, None, (("amplitude_mps", 10.0 * KT2MPS),
                                                              ("frequency_hz", 1.0)))),
        "three": tuple([FaultSpec(f"aoa{i}", "bias", 8.0, None, (("bias_rad", 4.0 * DEG2RAD),))
                        for i in range(3)]
                       + [FaultSpec(f"cas{i}", "runaway", 10.0, None,
                                    (("rate_mps_per_s", -10.0 * KT2MPS),
                                     ("limit_mps", 30.0 * KT2MPS))) for i in range(3)]),
    }


# ------------------------------------------------------------------------------------------------
# IMU (Lu2016, Atmaca2025)
# ------------------------------------------------------------------------------------------------


# Lu2016 secs. 3.3-3.5 scenarios with the Table 2 faults (10-30 s)
TABLE2_PRESETS = ("lu2016_calm", "lu2016_shear", "lu2016_turbulence", "lu2016_parabolic")
# lu2016_turbulence with only the accelerometer (gyro) faults of Table 2: isolation check
ISOLATION_VARIANTS = ("lu2016_turbulence:acc", "lu2016_turbulence:gyro")
ATMACA_PRESETS = ("atmaca2025_acc", "atmaca2025_gyro")
MANOEUVRES = ("level", "coordinated_turn", "parabolic", "doublet_3211", "s_turn")


def preset(name: str, *, seed: int | None = None, duration_s: float | None = None) -> Scenario:
    """A preset scenario (``sim_vehicle/presets``), optionally with another seed or length."""
    return with_overrides(load_scenario(name), seed=seed, duration_s=duration_s)


def fault_free_variant(manoeuvre: str, seed: int, *, duration_s: float = 60.0,
                       wind: str = "turbulence") -> Scenario:
    """lu2016_turbulence without faults, with another manoeuvre, wind and seed (in memory)."""
    sc = preset("lu2016_turbulence")
    return dataclasses.replace(
        sc, name=f"ff_{manoeuvre}_{wind}", faults=(), seed=seed, duration_s=duration_s,
        wind=dataclasses.replace(sc.wind, kind=wind),
        manoeuvre=dataclasses.replace(sc.manoeuvre, kind=manoeuvre, start_s=5.0))


def imu_group_only(sc: Scenario, group: str) -> Scenario:
    """``sc`` with only its faults on IMU 0's ``group`` (``"acc"`` or ``"gyro"``)."""
    return dataclasses.replace(sc, faults=tuple(
        f for f in sc.faults if f.channel.startswith(f"imu0.{group}.")))


def detection_scenario(spec: str, seed: int) -> Scenario:
    """A preset by name, or ``"<preset>:<group>"`` for the preset with only the faults of that
    IMU group (the isolation check), named ``<preset>_<group>``."""
    name, _, only = spec.partition(":")
    sc = preset(name, seed=seed)
    if only:
        sc = dataclasses.replace(imu_group_only(sc, only), name=spec.replace(":", "_"))
    return sc


def closed_loop_scenario(name: str, group: str, manoeuvre: str) -> Scenario:
    """A preset flown with another manoeuvre, with only the faults of one IMU group."""
    sc = imu_group_only(preset(name), group)
    return dataclasses.replace(sc, manoeuvre=dataclasses.replace(sc.manoeuvre, kind=manoeuvre))
