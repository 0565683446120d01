"""Every monitor configuration and estimator variant the experiments run with, in one place.

The experiments never build a :class:`MonitorConfig` or an estimator themselves: they call the
functions here, so a change of the configuration API is a change of this module only.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

from gcs_monitor.config import AirDataConfig, MonitorConfig
from gcs_monitor.config.loader import EstimatorsConfig, FdiConfig, SetConfig
from gcs_monitor.core.units import DEG2RAD, KT2MPS
from gcs_monitor.estimators.airdata import AirDataEstimator, AirDataEstimatorConfig
from gcs_monitor.estimators.base import Estimator
from gcs_monitor.estimators.imu_hosm import ImuHosmEstimator
from gcs_monitor.estimators.imu_ts import ImuTsConfig, ImuTwoStageEstimator, Lu2016Table1
from sim_vehicle.environment.wind import SHEAR_DURATION_S, SHEAR_VERTICAL_RATIO
from sim_vehicle.scenario import Scenario

EstimatorFactory = Callable[[], list[Estimator]]

# Thresholds no fault-free residual reaches: the FDI then never isolates (calibration runs).
OPEN_LOOP_AOA_RAD = 1.0e3
OPEN_LOOP_CAS_MPS = 1.0e4


# ------------------------------------------------------------------------------------------------
# air data (Wan2018)
# ------------------------------------------------------------------------------------------------


def _ceil_to(x: float, step: float) -> float:
    return math.ceil(round(abs(x) / step, 9)) * step


def declared_weather(sc: Scenario, base: AirDataConfig | None = None) -> AirDataConfig:
    """The weather a scenario declares, as the monitor receives it (a forecast).

    Built from the scenario's wind *specification* (kind, steady wind, shear amplitude, Dryden
    intensity and scale), never from the simulated wind samples, and coarsened as a forecast
    is: wind speed (not direction) rounded up to 5 kt, vertical wind to 1 kt, shear to 5 kt,
    turbulence intensity to 1 kt. Shear acceleration: the simulator's microburst
    (``sim_vehicle.environment.wind``) changes the wind by ``A`` over ``SHEAR_DURATION_S`` along
    ``A/2 (1 - cos(2 pi t / T))``, whose largest rate is ``pi A / T``. The other envelope fields
    (``n_sigma``, flight path) come from ``base``.
    """
    b = base or AirDataConfig()
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


def with_airdata(cfg: MonitorConfig, airdata: AirDataConfig) -> MonitorConfig:
    """``cfg`` with the ``[airdata]`` section (declared weather, model switches) replaced."""
    return dataclasses.replace(cfg, airdata=airdata)


def with_declared_weather(cfg: MonitorConfig, sc: Scenario) -> MonitorConfig:
    """``cfg`` receiving the scenario's declared weather (:func:`declared_weather`) as its
    ``[airdata]`` envelope, as a flight receives its forecast."""
    return with_airdata(cfg, declared_weather(sc, cfg.airdata))


def variant_config(variant: str, base: MonitorConfig | None = None, *,
                   lateral: bool = False, restart_peers: bool = False,
                   equal_pair: bool = False) -> MonitorConfig:
    """Air-data only (no IMU estimators: not part of these experiments), with Wan2018's
    wings-level model (eqs. 12-15) unless ``lateral`` asks for our bank and sideslip terms,
    Wan2018's per-instance windows unless ``restart_peers`` asks for our restart of the
    peers' windows on an isolation, and eq. 19's 1/J^2 weights for the last two instances
    unless ``equal_pair`` asks for our equal weights, whatever the monitor's defaults are:
    the reproductions use the paper's scheme."""
    cfg = base or MonitorConfig()
    sets = {s: dataclasses.replace(getattr(cfg.fdi, s), restart_peers=restart_peers,
                                   equal_pair_weights=equal_pair) for s in ("aoa", "cas")}
    cfg = dataclasses.replace(
        cfg, airdata=dataclasses.replace(cfg.airdata, lateral_terms=lateral),
        fdi=dataclasses.replace(cfg.fdi, **sets))
    return dataclasses.replace(cfg, estimators=EstimatorsConfig(imu_ts=False, imu_hosm=False,
                                                                airdata=variant))


def without_wind_accel(cfg: MonitorConfig) -> MonitorConfig:
    """``cfg`` on Wan2018's eq. 13 AoA model, without eq. 8's wind-acceleration term."""
    return with_airdata(cfg, dataclasses.replace(cfg.airdata, wind_accel_in_alpha=False))


def with_thresholds(cfg: MonitorConfig, aoa_rad: float, cas_mps: float,
                    aoa_per_turbulence: float = 0.0, cas_per_turbulence: float = 0.0
                    ) -> MonitorConfig:
    """``cfg`` with the AoA/CAS J_th (SI) and their growth per m/s of declared turbulence."""
    fdi = dataclasses.replace(
        cfg.fdi,
        aoa=dataclasses.replace(cfg.fdi.aoa, threshold=aoa_rad,
                                threshold_per_turbulence=aoa_per_turbulence),
        cas=dataclasses.replace(cfg.fdi.cas, threshold=cas_mps,
                                threshold_per_turbulence=cas_per_turbulence))
    return dataclasses.replace(cfg, fdi=fdi)


def open_loop(cfg: MonitorConfig) -> MonitorConfig:
    """``cfg`` with thresholds no residual reaches: every instance stays in the fusion."""
    return with_thresholds(cfg, OPEN_LOOP_AOA_RAD, OPEN_LOOP_CAS_MPS)


def consensus_config(base: MonitorConfig | None = None) -> MonitorConfig:
    """``base`` (default: the monitor's defaults) without an air-data estimator: the AoA/CAS
    residuals are taken against the set's own consensus."""
    cfg = base or MonitorConfig()
    return dataclasses.replace(cfg, estimators=dataclasses.replace(cfg.estimators,
                                                                   airdata="none"))


def light_aircraft_config() -> AirDataEstimatorConfig:
    """CMHE tuning for a light aircraft at 46-75 kts (configuration, not code; see
    docs/papers-notes.md, Wan2018, "Low speed (46-75 kt) and the OnSpeed tuning"). Model-error
    weights scaled by about (V_transport / V_light)^2 ~ 10-25 against the transport defaults;
    wind bounds for a calm-air flight-test day: |W_x| <= 15 m/s, |W_z| <= 3 m/s, wind rate
    <= 0.5 m/s^2."""
    return AirDataEstimatorConfig(
        dt_nominal_s=0.02,  # OnSpeed air data at 40-50 Hz
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
    """The CMHE with :func:`light_aircraft_config` (the OnSpeed replay's air-data estimator)."""
    return AirDataEstimator(light_aircraft_config(), "cmhe")


# ------------------------------------------------------------------------------------------------
# IMU (Lu2016, Atmaca2025)
# ------------------------------------------------------------------------------------------------


def set_thresholds(thresholds: dict[str, float], base: FdiConfig | None = None
                   ) -> dict[str, SetConfig]:
    """The FDI sets named in ``thresholds`` (from ``base``, default the defaults) with those
    J_th, SI: what :func:`imu_config` takes."""
    b = base or FdiConfig()
    return {name: dataclasses.replace(getattr(b, name), threshold=th)
            for name, th in thresholds.items()}


def imu_config(sets: dict[str, SetConfig] | None = None) -> MonitorConfig:
    """The IMU experiments' monitor: air-data estimation off (not under test here; the AoA/CAS
    sets still run on set consensus), the IMU channel sets ``sets`` (default: the defaults)."""
    base = MonitorConfig(estimators=EstimatorsConfig(airdata="none"))
    return base if sets is None else dataclasses.replace(
        base, fdi=dataclasses.replace(base.fdi, **sets))


def _named(est: Estimator, name: str) -> Estimator:
    est.name = name  # several variants on one Monitor: channel monitors are keyed by name
    return est


def lu2016_variants() -> list[Estimator]:
    """GS-KM/AS-KM x ATSEKF/IOTSEKF (Lu2016 secs. 3.3-3.5), Lu2016 Table 1 noise."""
    return [
        _named(ImuTwoStageEstimator(ImuTsConfig(model="gs", adaptive=True)), "gs_atsekf"),
        _named(ImuTwoStageEstimator(ImuTsConfig(model="gs", adaptive=False)), "gs_iotsekf"),
        _named(ImuTwoStageEstimator(ImuTsConfig(model="as", adaptive=True)), "as_atsekf"),
        _named(ImuTwoStageEstimator(ImuTsConfig(model="as", adaptive=False)), "as_iotsekf"),
    ]


def atmaca_noise() -> Lu2016Table1:
    """Atmaca2025 Table 1 sigmas in the Lu2016 estimator's noise dataclass (fair comparison)."""
    return Lu2016Table1(vel_sigma_mps=0.030, euler_sigma_rad=8.7e-5, acc_sigma_mps2=6.9e-4,
                        gyro_sigma_radps=4.1e-6, aoa_sigma_rad=2.7e-4, tas_sigma_mps=0.005)


def atmaca_variants() -> list[Estimator]:
    """OTSEKF+HOSM (Atmaca2025) and the IOTSEKF on the GS-KM with the same sensor noise."""
    return [
        _named(ImuHosmEstimator(), "otsekf_hosm"),
        _named(ImuTwoStageEstimator(ImuTsConfig(model="gs", adaptive=False,
                                                noise=atmaca_noise())), "gs_iotsekf"),
        _named(ImuTwoStageEstimator(ImuTsConfig(model="gs", adaptive=True,
                                                noise=atmaca_noise())), "gs_atsekf"),
    ]


def default_variant() -> list[Estimator]:
    """What the monitor runs by default (``MonitorConfig().estimators``: imu_ts, GS-KM ATSEKF)."""
    return [ImuTwoStageEstimator()]


def hosm_variant() -> list[Estimator]:
    """What the monitor runs with ``estimators.imu_hosm = true`` (and imu_ts off)."""
    return [ImuHosmEstimator()]


# estimator name -> (factory, FDI set names of its acc and gyro channels, MonitorConfig.fdi)
DETECTION_ESTIMATORS: dict[str, tuple[EstimatorFactory, tuple[str, str]]] = {
    "imu_ts": (default_variant, ("acc", "gyro")),
    "imu_hosm": (hosm_variant, ("acc_hosm", "gyro_hosm")),
}


def gs_atsekf_with(noise: Lu2016Table1, imu_rate_hz: float) -> list[Estimator]:
    """The monitor's GS-KM ATSEKF with sensor noise and IMU rate taken from a data source."""
    return [ImuTwoStageEstimator(ImuTsConfig(model="gs", adaptive=True, noise=noise,
                                             imu_rate_hz=imu_rate_hz))]
