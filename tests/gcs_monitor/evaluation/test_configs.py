"""Monitor configurations of the experiments (gcs_monitor.evaluation.configs)."""

from __future__ import annotations

import dataclasses
import math

import pytest

from gcs_monitor.core.units import KT2MPS
from gcs_monitor.evaluation import configs
from gcs_monitor.evaluation.scenarios import preset_set
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
    assert cfg.fdi.aoa.threshold >= 1.0e3 and cfg.fdi.cas.threshold >= 1.0e4
    assert cfg.estimators.airdata == "cmhe" and not cfg.estimators.imu_ts


def test_imu_config_sets_the_named_thresholds_only() -> None:
    sets = configs.set_thresholds({"acc": 0.7, "gyro_hosm": 0.01})
    cfg = configs.imu_config(sets)
    default = configs.imu_config()
    assert cfg.estimators.airdata == "none" and cfg.estimators.imu_ts
    assert cfg.fdi.acc.threshold == 0.7 and cfg.fdi.gyro_hosm.threshold == 0.01
    assert cfg.fdi.acc.n_eval == default.fdi.acc.n_eval  # only J_th changes
    assert cfg.fdi.gyro == default.fdi.gyro
