"""Monitor configurations of the experiments (gcs_monitor.evaluation.configs)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from gcs_monitor.config import MonitorConfig
from gcs_monitor.core.units import KT2MPS
from gcs_monitor.evaluation import configs
from gcs_monitor.evaluation.scenarios import preset_set
from gcs_monitor.families.airdata.family import AirDataFamily
from gcs_monitor.families.base import FamilyContext
from gcs_monitor.families.imu.family import ImuFamily
from sim_vehicle.environment.wind import SHEAR_DURATION_S
from sim_vehicle.scenario import WindSpec


def test_declared_weather_is_the_scenario_forecast_rounded_up() -> None:
    """The monitor receives the scenario's wind *specification* coarsened like a forecast:
    speed 5 kt steps, vertical 1 kt, shear 5 kt, sigma 1 kt; shear rate pi A / T (A/2 (1 - cos))."""
    sc = preset_set("triplex", 1, 0)[0]
    w = WindSpec(kind="shear+turbulence", mean_ned_mps=(3.0, 4.0, -0.6),
                 turbulence_sigma_mps=2.51, shear_amplitude_mps=10.0)
    a = configs.declared_weather(dataclasses.replace(sc, wind=w))
    assert a.wind_mps == pytest.approx(10.0 * KT2MPS)  # 5 m/s = 9.7 kt -> 10 kt
    assert a.wind_z_mps == pytest.approx(2.0 * KT2MPS)  # 0.6 m/s = 1.2 kt -> 2 kt
    assert a.turbulence_sigma_mps == pytest.approx(5.0 * KT2MPS)  # 4.88 kt -> 5 kt
    assert a.shear_mps == pytest.approx(20.0 * KT2MPS)  # 19.4 kt -> 20 kt
    assert a.shear_rate_mps2 == pytest.approx(math.pi * 20.0 * KT2MPS / SHEAR_DURATION_S)
    calm = configs.declared_weather(dataclasses.replace(sc, wind=dataclasses.replace(w,
                                                                                   kind="calm")))
    assert calm.wind_mps == calm.shear_mps == calm.turbulence_sigma_mps == 0.0


def test_calibration_runs_open_loop() -> None:
    """Calibration runs must never isolate (a lost set would leave the MHE on the model alone and
    inflate the 'fault-free' J): open_loop thresholds sit far above any residual."""
    cfg = configs.open_loop(configs.variant_config("cmhe"))
    air = cfg.family("airdata")
    assert air.fdi.aoa.threshold >= 1.0e3 and air.fdi.cas.threshold >= 1.0e4
    assert air.estimator == "cmhe" and not cfg.family("imu").enabled


def test_variant_config_is_the_papers_scheme_whatever_the_defaults() -> None:
    """The reproductions run Wan2018's wings-level model, per-instance windows and eq. 19
    weights; the switches turn our extensions on; the weather stays the base's."""
    base = MonitorConfig()
    assert base.family("airdata").filter.lateral_terms
    assert base.family("airdata").fdi.aoa.restart_peers
    paper = configs.variant_config("umhe", base).family("airdata")
    assert paper.estimator == "umhe" and not paper.filter.lateral_terms
    assert not paper.fdi.aoa.restart_peers and not paper.fdi.cas.restart_peers
    assert not paper.fdi.aoa.equal_pair_weights
    assert paper.weather == base.family("airdata").weather
    ours = configs.variant_config("cmhe", lateral=True, restart_peers=True,
                                  equal_pair=True).family("airdata")
    assert ours.filter.lateral_terms and ours.fdi.cas.restart_peers
    assert ours.fdi.aoa.equal_pair_weights
    eq13 = configs.without_wind_accel(configs.variant_config("cmhe")).family("airdata")
    assert not eq13.filter.wind_accel_in_alpha and not eq13.filter.lateral_terms
    # the figures' setting: the declared weather alone, as in Wan2018
    assert paper.weather_estimate.enabled
    declared_only = configs.variant_config("cmhe", weather_estimate=False).family("airdata")
    assert not declared_only.weather_estimate.enabled


def test_declared_weather_reaches_the_family() -> None:
    sc = preset_set("triplex", 1, 0)[0]
    cfg = configs.with_declared_weather(configs.variant_config("cmhe"), sc)
    assert cfg.family("airdata").weather == configs.declared_weather(sc)
    assert not cfg.family("airdata").filter.lateral_terms  # model switches kept
    th = configs.with_thresholds(cfg, 0.02, 3.0, 0.01, 0.5).family("airdata").fdi
    assert (th.aoa.threshold, th.aoa.threshold_per_turbulence) == (0.02, 0.01)
    assert (th.cas.threshold, th.cas.threshold_per_turbulence) == (3.0, 0.5)
    assert configs.consensus_config().family("airdata").estimator == "none"


def test_windows_in_samples_of_the_streams() -> None:
    """Wan2018's N_eval = 10, n_D = 5 at the simulator's 20 Hz air data; the IMU channels'
    50 / 40 at its 100 Hz IMU; a 50 Hz stream gets 0.5 s windows too."""
    cfg = MonitorConfig()
    aoa = cfg.family("airdata").fdi.aoa
    acc = cfg.family("imu").ts.fdi.acc
    air_s, imu_s = configs.sim_air_period_s(), configs.sim_imu_period_s()
    assert (air_s, imu_s) == (0.05, 0.01)
    assert (configs.window_n(aoa, air_s), configs.detect_n(aoa, air_s)) == (10, 5)
    assert (configs.window_n(acc, imu_s), configs.detect_n(acc, imu_s)) == (50, 40)
    assert configs.window_n(acc, 0.02) == 25
    t = np.arange(0.0, 3.0, 0.02) + 1.0e-6 * np.sin(np.arange(150))
    assert configs.measured_period_s(t) == pytest.approx(0.02, abs=1e-5)


def test_imu_config_sets_the_named_thresholds_only() -> None:
    imu = configs.with_imu_thresholds(configs.imu_running("imu_hosm"), 0.7, 0.01, "imu_hosm")
    cfg = configs.imu_config(imu)
    default = configs.imu_config()
    assert cfg.family("airdata").estimator == "none"
    assert default.family("imu").ts.enabled and not default.family("imu").hosm.enabled
    fam = cfg.family("imu")
    assert fam.hosm.enabled and not fam.ts.enabled
    assert fam.hosm.fdi.acc.threshold == 0.7 and fam.hosm.fdi.gyro.threshold == 0.01
    assert fam.hosm.fdi.acc.window_s == default.family("imu").hosm.fdi.acc.window_s
    assert fam.ts.fdi == default.family("imu").ts.fdi  # only that estimator's J_th change
    assert configs.imu_fdi_sets(fam, "imu_hosm") is fam.hosm.fdi
    noisy = configs.with_imu_noise(fam, configs.atmaca_noise())
    assert noisy.ts.estimator.noise == configs.atmaca_noise() and noisy.ts.estimator.adaptive


def test_families_for_hands_variants_to_their_families() -> None:
    """Variants replace a family's estimators, each judged with its own thresholds; the other
    families come from the configuration, in registry order."""
    cfg = configs.imu_config()
    ctx = FamilyContext(vehicle=1, stale_after_s=0.5)
    fams = configs.families_for(cfg, imu=configs.atmaca_variants)(ctx)
    assert [f.name for f in fams] == ["imu", "airdata"]
    imu = fams[0]
    assert isinstance(imu, ImuFamily)
    assert [e.name for e in imu.estimators] == ["otsekf_hosm", "gs_iotsekf", "gs_atsekf"]
    air = configs.families_for(configs.variant_config("cmhe"),
                               airdata=configs.light_aircraft_estimator)(ctx)
    assert [f.name for f in air] == ["airdata"]  # [imu] off
    assert isinstance(air[0], AirDataFamily) and air[0].estimator is not None
    assert air[0].estimator.cfg.envelope is None  # fixed wind bounds, not the declared weather
    default = configs.families_for(MonitorConfig())(ctx)
    assert [f.name for f in default] == ["imu", "airdata", "yaw_rate", "actuators"]
