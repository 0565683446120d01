"""Every monitor configuration and estimator variant the experiments run with, in one place.

The experiments never build a :class:`MonitorConfig`, a family or an estimator themselves: they
call the functions here, so a change of the configuration API is a change of this module only.
Variants are configuration wherever the family configuration can express them (the air-data
estimator and model switches, the declared weather, the IMU estimator and its noise, every
threshold and window); only sets of estimators that the monitor never runs together (the
Lu2016 and Atmaca2025 comparisons) and the light-aircraft CMHE with fixed wind bounds are
handed to the families as objects (:func:`families_for`).

Windows are in seconds in the configuration; where an experiment needs them as sample counts
(calibrating J_th over N_eval-sample windows, the n_D/N_eval of a report) they are converted
with the period of the stream they apply to (:func:`window_n`, :func:`detect_n`): the
simulator's 20 Hz air data and 100 Hz IMU (:func:`sim_air_period_s`, :func:`sim_imu_period_s`),
or the measured period of a real flight (:func:`measured_period_s`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any

import numpy as np

from gcs_monitor.config import MonitorConfig
from gcs_monitor.core.units import DEG2RAD, KT2MPS
from gcs_monitor.families import registry
from gcs_monitor.families.airdata.config import AirDataFamilyConfig
from gcs_monitor.families.airdata.estimator import AirDataEstimator, AirDataEstimatorConfig
from gcs_monitor.families.airdata.family import AirDataFamily
from gcs_monitor.families.base import Family, FamilyContext, FaultEstimator
from gcs_monitor.families.imu.config import ImuFamilyConfig, ImuFdiSets
from gcs_monitor.families.imu.family import ImuFamily
from gcs_monitor.families.imu.imu_hosm import ImuHosmEstimator
from gcs_monitor.families.imu.imu_ts import ImuTsConfig, ImuTwoStageEstimator, Lu2016Table1
from gcs_monitor.fdi.config import ChannelSetConfig, channel_params
from gcs_monitor.models.airdata import WindEnvelope
from sim_vehicle.environment.wind import SHEAR_DURATION_S, SHEAR_VERTICAL_RATIO
from sim_vehicle.scenario import Scenario
from sim_vehicle.sensors.noise import SensorRates

# IMU estimators handed to the IMU family with the FDI sets that judge them
ImuVariants = Callable[[ImuFamilyConfig], list[tuple[FaultEstimator, ImuFdiSets]]]
AirDataVariant = Callable[[], AirDataEstimator]
FamiliesFactory = Callable[[FamilyContext], list[Family]]

# Thresholds no fault-free residual reaches: the FDI then never isolates (calibration runs).
OPEN_LOOP_AOA_RAD = 1.0e3
OPEN_LOOP_CAS_MPS = 1.0e4


# ------------------------------------------------------------------------------------------------
# families and sample counts
# ------------------------------------------------------------------------------------------------


def families_for(cfg: MonitorConfig, *, imu: ImuVariants | None = None,
                 airdata: AirDataVariant | None = None) -> FamiliesFactory:
    """``Monitor(families_for=...)``: the enabled families of ``cfg`` in registry order, the
    IMU family running the estimators of ``imu`` instead of its configured ones (built whether
    ``[imu]`` enables it or not) and the air-data family the estimator of ``airdata``."""

    def build(ctx: FamilyContext) -> list[Family]:
        out: list[Family] = []
        for spec in registry.FAMILIES:
            fam_cfg = cfg.families.get(spec.name)
            if spec.name == "imu" and imu is not None:
                out.append(ImuFamily(cfg.family("imu"), ctx,
                                     estimators=imu(cfg.family("imu"))))
            elif spec.name == "airdata" and airdata is not None:
                out.append(AirDataFamily(cfg.family("airdata"), ctx, estimator=airdata()))
            elif fam_cfg is not None and fam_cfg.enabled:
                out.append(spec.build(fam_cfg, ctx))
        return out

    return build


def sim_air_period_s(sc: Scenario | None = None) -> float:
    """Period of the simulator's air data (of ``sc``; default: the simulator's default rate,
    20 Hz), s."""
    rates = sc.sensors.rates if sc is not None else SensorRates()
    return 1.0 / rates.airdata_hz


def sim_imu_period_s(sc: Scenario | None = None) -> float:
    """Period of the simulator's IMU (of ``sc``; default 100 Hz), s."""
    rates = sc.sensors.rates if sc is not None else SensorRates()
    return 1.0 / rates.imu_hz


def measured_period_s(t_s: np.ndarray) -> float:
    """The sample period of a recorded stream: median interval of its times (s)."""
    return float(np.median(np.diff(t_s)))


def window_n(cfg: ChannelSetConfig, period_s: float) -> int:
    """N_eval: samples of the residual RMS window of ``cfg`` on a stream of period ``period_s``
    (as the monitor sizes it, :func:`gcs_monitor.fdi.config.channel_params`)."""
    return channel_params(cfg, period_s).rms.rms_window_n


def detect_n(cfg: ChannelSetConfig, period_s: float) -> int:
    """n_D: exceeding samples of the N_eval window that confirm a fault (as the monitor)."""
    return channel_params(cfg, period_s).confirmation.detect_n


# ------------------------------------------------------------------------------------------------
# air data (Wan2018)
# ------------------------------------------------------------------------------------------------


def _ceil_to(x: float, step: float) -> float:
    return math.ceil(round(abs(x) / step, 9)) * step


def declared_weather(sc: Scenario, base: WindEnvelope | None = None) -> WindEnvelope:
    """The weather a scenario declares, as the monitor receives it (a forecast).

    Built from the scenario's wind *specification* (kind, steady wind, shear amplitude, Dryden
    intensity and scale), never from the simulated wind samples, and coarsened as a forecast
    is: wind speed (not direction) rounded up to 5 kt, vertical wind to 1 kt, shear to 5 kt,
    turbulence intensity to 1 kt. Shear acceleration: the simulator's microburst
    (``sim_vehicle.environment.wind``) changes the wind by ``A`` over ``SHEAR_DURATION_S`` along
    ``A/2 (1 - cos(2 pi t / T))``, whose largest rate is ``pi A / T``. The other envelope fields
    (``n_sigma``, flight path, model margins) come from ``base`` (default: ``[airdata.weather]``
    defaults).
    """
    b = base or WindEnvelope()
    w = sc.wind
    kt = KT2MPS
    mean = (0.0, 0.0, 0.0) if w.kind == "calm" else w.mean_ned_mps
    wind = _ceil_to(math.hypot(mean[0], mean[1]) / kt, 5.0) * kt
    wind_z = _ceil_to(mean[2] / kt, 1.0) * kt
    shear = shear_z = shear_rate = 0.0
    if "shear" in w.kind:
        shear = _ceil_to(w.shear_amplitude_mps / kt, 5.0) * kt
        shear_z = SHEAR_VERTICAL_RATIO * shear
        shear_rate = math.pi * shear / SHEAR_DURATION_S
    sigma = _ceil_to(w.turbulence_sigma_mps / kt, 1.0) * kt if "turbulence" in w.kind else 0.0
    return dataclasses.replace(b, wind_mps=wind, wind_z_mps=wind_z, shear_mps=shear,
                               shear_z_mps=shear_z, shear_rate_mps2=shear_rate,
                               turbulence_sigma_mps=sigma,
                               turbulence_scale_m=w.turbulence_scale_m)


def airdata_of(cfg: MonitorConfig) -> AirDataFamilyConfig:
    """The ``[airdata]`` family configuration of ``cfg``."""
    air: AirDataFamilyConfig = cfg.family("airdata")
    return air


def weather_of(cfg: MonitorConfig) -> WindEnvelope:
    """The declared weather ``[airdata.weather]`` of ``cfg``."""
    return airdata_of(cfg).weather


def with_weather(cfg: MonitorConfig, weather: WindEnvelope) -> MonitorConfig:
    """``cfg`` with the declared weather ``[airdata.weather]`` replaced."""
    return cfg.with_family("airdata", weather=weather)


def with_declared_weather(cfg: MonitorConfig, sc: Scenario) -> MonitorConfig:
    """``cfg`` receiving the scenario's declared weather (:func:`declared_weather`) as its
    ``[airdata.weather]``, as a flight receives its forecast."""
    return with_weather(cfg, declared_weather(sc, weather_of(cfg)))


def _with_filter(cfg: MonitorConfig, **changes: Any) -> MonitorConfig:
    air = airdata_of(cfg)
    return cfg.with_family("airdata", filter=dataclasses.replace(air.filter, **changes))


def with_weather_estimate(cfg: MonitorConfig, **changes: Any) -> MonitorConfig:
    """``cfg`` with ``changes`` applied to the air-data weather estimate
    (``[airdata.estimate]``)."""
    air = airdata_of(cfg)
    return cfg.with_family("airdata", weather_estimate=dataclasses.replace(
        air.weather_estimate, **changes))


def _with_sets(cfg: MonitorConfig, **changes: Any) -> MonitorConfig:
    """``cfg`` with ``changes`` applied to both air-data sets (``[airdata.fdi.aoa]``, ``.cas``)."""
    fdi = airdata_of(cfg).fdi
    return cfg.with_family("airdata", fdi=dataclasses.replace(
        fdi, aoa=dataclasses.replace(fdi.aoa, **changes),
        cas=dataclasses.replace(fdi.cas, **changes)))


def family_alone(cfg: MonitorConfig, family: str) -> MonitorConfig:
    """``cfg`` with one family's estimators alone (a campaign of its alarms runs without the
    others' cost): every other family off, the air-data family without its estimator (its
    sets are still voted)."""
    for name in cfg.families:
        if name != family:
            cfg = (cfg.with_family(name, estimator="none") if name == "airdata"
                   else cfg.with_family(name, enabled=False))
    return cfg


def without_actuators(cfg: MonitorConfig) -> MonitorConfig:
    """``cfg`` with the actuator family off: the sensor experiments judge their own families
    (its experiments are in :mod:`gcs_monitor.evaluation.papers.actuators`)."""
    return cfg.with_family("actuators", enabled=False)


def variant_config(variant: str, base: MonitorConfig | None = None, *,
                   lateral: bool = False, restart_peers: bool = False,
                   equal_pair: bool = False, weather_estimate: bool = True) -> MonitorConfig:
    """Air-data only (the IMU and yaw-rate families off: not part of these experiments), with
    Wan2018's wings-level model (eqs. 12-15) unless ``lateral`` asks for our bank and sideslip
    terms,
    Wan2018's per-instance windows unless ``restart_peers`` asks for our restart of the
    peers' windows on an isolation, and eq. 19's 1/J^2 weights for the last two instances
    unless ``equal_pair`` asks for our equal weights, whatever the monitor's defaults are:
    the reproductions use the paper's scheme. ``weather_estimate`` False leaves the bounds to
    the declared weather alone, as in the paper (the figure reproductions); the campaigns keep
    the monitor's estimate on top of it (their results were measured so)."""
    cfg = _with_sets(base or MonitorConfig(), restart_peers=restart_peers,
                     equal_pair_weights=equal_pair)
    cfg = _with_filter(cfg, lateral_terms=lateral)
    if not weather_estimate:
        cfg = with_weather_estimate(cfg, enabled=False)
    return (cfg.with_family("airdata", estimator=variant).with_family("imu", enabled=False)
            .with_family("yaw_rate", enabled=False).with_family("actuators", enabled=False))


def without_wind_accel(cfg: MonitorConfig) -> MonitorConfig:
    """``cfg`` on Wan2018's eq. 13 AoA model, without eq. 8's wind-acceleration term."""
    return _with_filter(cfg, wind_accel_in_alpha=False)


def with_thresholds(cfg: MonitorConfig, aoa_rad: float, cas_mps: float,
                    aoa_per_turbulence: float = 0.0, cas_per_turbulence: float = 0.0
                    ) -> MonitorConfig:
    """``cfg`` with the AoA/CAS J_th (SI) and their growth per m/s of declared turbulence."""
    fdi = airdata_of(cfg).fdi
    return cfg.with_family("airdata", fdi=dataclasses.replace(
        fdi,
        aoa=dataclasses.replace(fdi.aoa, threshold=aoa_rad,
                                threshold_per_turbulence=aoa_per_turbulence),
        cas=dataclasses.replace(fdi.cas, threshold=cas_mps,
                                threshold_per_turbulence=cas_per_turbulence)))


def open_loop(cfg: MonitorConfig) -> MonitorConfig:
    """``cfg`` with thresholds no residual reaches: every instance stays in the fusion."""
    return with_thresholds(cfg, OPEN_LOOP_AOA_RAD, OPEN_LOOP_CAS_MPS)


def consensus_config(base: MonitorConfig | None = None) -> MonitorConfig:
    """``base`` (default: the monitor's defaults) without an air-data estimator: the AoA/CAS
    residuals are taken against the set's own consensus."""
    return (base or without_actuators(MonitorConfig())).with_family("airdata", estimator="none")


def light_aircraft_config() -> AirDataEstimatorConfig:
    """CMHE tuning for a light aircraft at 46-75 kts (configuration, not code; see
    docs/papers-notes.md, Wan2018, "Low speed (46-75 kt) and the OnSpeed tuning"). Model-error
    weights scaled by about (V_transport / V_light)^2 ~ 10-25 against the transport defaults;
    fixed wind bounds for a calm-air flight-test day (no declared weather envelope):
    |W_x| <= 15 m/s, |W_z| <= 3 m/s, wind rate <= 0.5 m/s^2. The estimator takes the air-data
    period (OnSpeed: 40-50 Hz) from the samples."""
    return AirDataEstimatorConfig(
        q_alpha_rad2ps2=1.0e-2,  # 1/V_t ~ 1/V_g and f_w,alpha/V_t errors ~ 0.1 rad/s
        q_v_m2ps4=4.0,
        r_vz_m2ps2=0.25,
        r_alpha_rad2=(0.3 * DEG2RAD) ** 2,
        r_vc_m2ps2=1.0,
        wind_x_max_mps=15.0,
        wind_z_max_mps=3.0,
        wind_rate_max_mps2=0.5,
    )


def light_aircraft_estimator() -> AirDataEstimator:
    """The CMHE with :func:`light_aircraft_config` (the OnSpeed replay's air-data estimator).

    Handed to the air-data family as an object: the family gives its estimator the declared
    weather ``[airdata.weather]`` as its wind envelope, and this tuning uses fixed bounds
    instead (``envelope=None``), which the configuration cannot select."""
    return AirDataEstimator(light_aircraft_config(), "cmhe")


# ------------------------------------------------------------------------------------------------
# IMU (Lu2016, Atmaca2025)
# ------------------------------------------------------------------------------------------------

# the monitor's IMU estimators by name -> their section of ``[imu]``
IMU_SECTIONS = {"imu_ts": "ts", "imu_hosm": "hosm"}


def imu_of(cfg: MonitorConfig) -> ImuFamilyConfig:
    """The ``[imu]`` family configuration of ``cfg``."""
    imu: ImuFamilyConfig = cfg.family("imu")
    return imu


def imu_fdi_sets(imu: ImuFamilyConfig, estimator: str = "imu_ts") -> ImuFdiSets:
    """The FDI sets of the monitor's IMU estimator ``estimator`` (``[imu.ts.fdi]`` or
    ``[imu.hosm.fdi]``)."""
    sets: ImuFdiSets = getattr(imu, IMU_SECTIONS[estimator]).fdi
    return sets


def imu_running(estimator: str, base: ImuFamilyConfig | None = None) -> ImuFamilyConfig:
    """``base`` (default: the ``[imu]`` defaults) running only the monitor's IMU estimator
    ``estimator`` (``imu_ts``: Lu2016 GS-KM ATSEKF; ``imu_hosm``: Atmaca2025 OTSEKF+HOSM)."""
    b = base or ImuFamilyConfig()
    if estimator not in IMU_SECTIONS:
        raise KeyError(f"unknown IMU estimator {estimator!r}; known: {sorted(IMU_SECTIONS)}")
    return dataclasses.replace(
        b, enabled=True, ts=dataclasses.replace(b.ts, enabled=estimator == "imu_ts"),
        hosm=dataclasses.replace(b.hosm, enabled=estimator == "imu_hosm"))


def with_imu_thresholds(imu: ImuFamilyConfig, acc: float, gyro: float,
                        estimator: str = "imu_ts") -> ImuFamilyConfig:
    """``imu`` with the accelerometer and gyro J_th (SI) of ``estimator``'s fault channels."""
    name = IMU_SECTIONS[estimator]
    sec = getattr(imu, name)
    fdi = dataclasses.replace(sec.fdi, acc=dataclasses.replace(sec.fdi.acc, threshold=acc),
                              gyro=dataclasses.replace(sec.fdi.gyro, threshold=gyro))
    return dataclasses.replace(imu, **{name: dataclasses.replace(sec, fdi=fdi)})


def with_imu_noise(imu: ImuFamilyConfig, noise: Lu2016Table1) -> ImuFamilyConfig:
    """``imu`` whose Lu2016 estimator (GS-KM ATSEKF) assumes the sensor noise ``noise`` (of a
    data source)."""
    est = dataclasses.replace(imu.ts.estimator, model="gs", adaptive=True, noise=noise)
    return dataclasses.replace(imu, ts=dataclasses.replace(imu.ts, estimator=est))


def imu_config(imu: ImuFamilyConfig | None = None) -> MonitorConfig:
    """The IMU experiments' monitor: air-data estimation off (not under test here; the AoA/CAS
    sets still run on set consensus), the yaw-rate family off (it judges the yaw-rate gyro
    too, with its own estimator: not these papers'), the actuator family off, the IMU family
    ``imu`` (default: the ``[imu]`` defaults, the Lu2016 estimator alone)."""
    base = (without_actuators(MonitorConfig()).with_family("airdata", estimator="none")
            .with_family("yaw_rate", enabled=False))
    return base if imu is None else base.with_family("imu", imu)


def _named(est: FaultEstimator, name: str) -> FaultEstimator:
    est.name = name  # several variants in one family: channel monitors are keyed by name
    return est


def lu2016_variants(imu: ImuFamilyConfig) -> list[tuple[FaultEstimator, ImuFdiSets]]:
    """GS-KM/AS-KM x ATSEKF/IOTSEKF (Lu2016 secs. 3.3-3.5), Lu2016 Table 1 noise, judged with
    the Lu2016 estimator's thresholds."""
    sets = imu.ts.fdi
    return [
        (_named(ImuTwoStageEstimator(ImuTsConfig(model="gs", adaptive=True)), "gs_atsekf"), sets),
        (_named(ImuTwoStageEstimator(ImuTsConfig(model="gs", adaptive=False)), "gs_iotsekf"),
         sets),
        (_named(ImuTwoStageEstimator(ImuTsConfig(model="as", adaptive=True)), "as_atsekf"), sets),
        (_named(ImuTwoStageEstimator(ImuTsConfig(model="as", adaptive=False)), "as_iotsekf"),
         sets),
    ]


def atmaca_noise() -> Lu2016Table1:
    """Atmaca2025 Table 1 sigmas in the Lu2016 estimator's noise dataclass (fair comparison)."""
    return Lu2016Table1(vel_sigma_mps=0.030, euler_sigma_rad=8.7e-5, acc_sigma_mps2=6.9e-4,
                        gyro_sigma_radps=4.1e-6, aoa_sigma_rad=2.7e-4, tas_sigma_mps=0.005)


def atmaca_variants(imu: ImuFamilyConfig) -> list[tuple[FaultEstimator, ImuFdiSets]]:
    """OTSEKF+HOSM (Atmaca2025) and the IOTSEKF on the GS-KM with the same sensor noise, each
    judged with its estimator's thresholds."""
    return [
        (_named(ImuHosmEstimator(), "otsekf_hosm"), imu.hosm.fdi),
        (_named(ImuTwoStageEstimator(ImuTsConfig(model="gs", adaptive=False,
                                                 noise=atmaca_noise())), "gs_iotsekf"),
         imu.ts.fdi),
        (_named(ImuTwoStageEstimator(ImuTsConfig(model="gs", adaptive=True,
                                                 noise=atmaca_noise())), "gs_atsekf"),
         imu.ts.fdi),
    ]
