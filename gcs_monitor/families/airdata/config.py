"""Configuration of the air-data family: TOML section ``[airdata]``.

Triplex AoA and CAS judged against the Wan2018 model's one-step-ahead prediction (eq. 17), with
the declared weather from which the constrained MHE takes its wind bounds (eq. 21b) and, with a
slope, the thresholds their growth with turbulence.
"""

from __future__ import annotations

from dataclasses import dataclass

from gcs_monitor.core.params import DEG, KTS, param, section
from gcs_monitor.core.units import DEG2RAD, KT2MPS
from gcs_monitor.families.airdata.estimator import VARIANTS, AirDataEstimatorConfig
from gcs_monitor.families.airdata.weather import WeatherConfig
from gcs_monitor.fdi.config import RedundantSetConfig
from gcs_monitor.models.airdata import WindEnvelope

ESTIMATORS = (*VARIANTS, "none")


@dataclass(frozen=True, slots=True)
class AirDataFdiSets:
    """The redundant air-data sets (Wan2018 sec. III-A; noise: the simulated vanes' and
    pitots', Lu2016 Table 1; runaway rates separate Wan2018 Table II drifts from runaways)."""

    aoa: RedundantSetConfig = section(
        lambda: RedundantSetConfig(threshold=1.0 * DEG2RAD, noise_sigma=0.1 * DEG2RAD,
                                   runaway_rate=1.0 * DEG2RAD),
        "angle-of-attack vanes (Wan2018: J_th 2.9 deg on its airframe)", unit=DEG)
    cas: RedundantSetConfig = section(
        lambda: RedundantSetConfig(threshold=4.0 * KT2MPS, noise_sigma=0.1,
                                   runaway_rate=2.0 * KT2MPS),
        "calibrated-airspeed probes (Wan2018: J_th 12 kt on its airframe)", unit=KTS)


@dataclass(frozen=True, slots=True)
class FusionConfig:
    """The fused measurement the MHE receives (gcs_monitor.fdi.fusion)."""

    weight_floor_ratio: float = param(0.25, "floor on J in the eq. 19 weights, as a fraction "
                                      "of J_th (residual RMS below the fault-free level carries "
                                      "no fault information)", positive=True)


@dataclass(frozen=True, slots=True)
class AirDataFamilyConfig:
    """Triplex air data (Wan2018): CMHE reference, residual RMS, adaptive fusion, Table I."""

    enabled: bool = param(True, "monitor the air-data family")
    estimator: str = param("cmhe", "model reference of the sets: cmhe (Wan2018 constrained "
                           "MHE), umhe, ekf, or none (each instance against the set's "
                           "consensus)", choices=ESTIMATORS)
    weather: WindEnvelope = section(WindEnvelope, "declared weather of the flight (a forecast): "
                                    "the CMHE's wind bounds (Wan2018 eq. 21b) and the scheduled "
                                    "thresholds follow it; with [airdata.weather_estimate] on, it "
                                    "is the prior until the estimate has converged")
    wind_bounds: str = param("weather", "where the CMHE's wind bounds (eq. 21b) come from: "
                             "weather (the estimated or declared weather, at every sample) or "
                             "fixed ([airdata.filter] wind_x_max_mps, wind_z_max_mps, "
                             "wind_rate_max_mps2)", choices=("weather", "fixed"))
    weather_estimate: WeatherConfig = section(WeatherConfig, "the weather estimated online from "
                                              "GPS velocity, attitude and the fused air data")
    filter: AirDataEstimatorConfig = section(
        lambda: AirDataEstimatorConfig(lateral_terms=True),
        "tuning of the Wan2018 estimator (bank and sideslip in eqs. 12-15 on by default: a "
        "calm 31 deg-bank s-turn otherwise gives 1.2 deg of fault-free AoA J)")
    fdi: AirDataFdiSets = section(AirDataFdiSets, "the redundant sets")
    fusion: FusionConfig = section(FusionConfig, "eq. 19 fusion fed to the estimator")
