"""Monitor config: defaults, unit conversion at load, and one focused test per validation rule."""

from __future__ import annotations

import math

import pytest

from gcs_monitor.config import ConfigError, load_config


def _write(tmp_path, text):
    p = tmp_path / "monitor.toml"
    p.write_text(text)
    return p


def test_defaults_run_without_a_file():
    c = load_config(None)
    assert c.fdi.aoa.n_eval == 10  # Wan2018: N_eval = 10
    assert c.estimators.airdata == "cmhe"


def test_units_converted_once(tmp_path):
    c = load_config(_write(tmp_path,
                           "[fdi.aoa]\nthreshold_deg = 2.0\n[fdi.cas]\nthreshold_kts = 10\n"))
    assert c.fdi.aoa.threshold == pytest.approx(math.radians(2.0), rel=1e-12)
    assert c.fdi.cas.threshold == pytest.approx(10 * 1852 / 3600, rel=1e-12)


def test_imu_hosm_thresholds_are_their_own_keys(tmp_path):
    c = load_config(_write(tmp_path, "[estimators]\nimu_hosm = true\n"
                           "[fdi.acc_hosm]\nthreshold_mps2 = 0.9\n"
                           "[fdi.gyro_hosm]\nthreshold_degps = 0.8\n"))
    assert c.estimators.imu_hosm
    assert c.fdi.acc_hosm.threshold == pytest.approx(0.9, rel=1e-12)
    assert c.fdi.gyro_hosm.threshold == pytest.approx(math.radians(0.8), rel=1e-12)
    # the ATSEKF thresholds are untouched
    assert c.fdi.acc.threshold == load_config(None).fdi.acc.threshold


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("[nope]\n", r"unknown section \[nope\]"),
        ("[sinks]\nrerun_hz = 3\n", r"unknown key 'sinks.rerun_hz'"),
        ("[fdi.aoa]\nthreshold_kts = 3\n", r"given as 'threshold_deg'"),
        ("[fdi.aoa]\nn_detect = 11\n", r"must not exceed n_eval"),
        ("[estimators]\nairdata = 'kalman'\n", r"must be one of"),
        ("[telemetry]\ngps_delay_s = 'x'\n", r"must be a non-negative number"),
        ("[fdi]\nbaro = {}\n", r"unknown key 'fdi.baro'"),
        ("x = [", r"not valid TOML"),
        ("[fdi.gyro_hosm]\nthreshold_mps2 = 0.5\n", r"given as 'threshold_degps'"),
        ("[fdi.acc_hosm]\nthreshold_mps2 = -1\n",
         r"'fdi.acc_hosm.threshold_mps2' must be a positive"),
        ("[fdi.acc_hosm]\nn_detect = 60\n", r"must not exceed n_eval"),
        ("[fdi.aoa]\nstuck_window_s = 0.1\n", r"'fdi.aoa.stuck_window_s' must be 0 \(off\)"),
        ("[fdi.cas]\nno_data_window_s = -1\n",
         r"'fdi.cas.no_data_window_s' must be a non-negative number"),
        ("[airdata]\nwind_mps = 3\n", r"unknown key 'airdata.wind_mps'"),
        ("[airdata]\nturbulence_sigma_kts = -1\n", r"must be a non-negative number"),
        ("[airdata]\nwind_accel_in_alpha = 1\n", r"must be true or false"),
    ],
)
def test_invalid_config_names_file_and_key(tmp_path, text, match):
    p = _write(tmp_path, text)
    with pytest.raises(ConfigError, match=match) as ei:
        load_config(p)
    assert str(p) in str(ei.value)


def test_shipped_imu_hosm_config_loads():
    from pathlib import Path

    c = load_config(Path(__file__).parents[3] / "configs" / "imu_hosm.toml")
    assert c.estimators.imu_hosm and not c.estimators.imu_ts
    assert c.fdi.acc_hosm.threshold == load_config(None).fdi.acc_hosm.threshold


def test_airdata_envelope_in_knots(tmp_path):
    """[airdata]: the declared weather, knots in the file, SI after loading."""
    c = load_config(_write(tmp_path, "[airdata]\nwind_kts = 30\nturbulence_sigma_kts = 4\n"
                                     "shear_rate_ktsps = 2\nflight_path_max_deg = 5\n"))
    kt = 1852 / 3600
    assert c.airdata.wind_mps == pytest.approx(30 * kt, rel=1e-12)
    assert c.airdata.turbulence_sigma_mps == pytest.approx(4 * kt, rel=1e-12)
    assert c.airdata.shear_rate_mps2 == pytest.approx(2 * kt, rel=1e-12)
    assert c.airdata.flight_path_max_rad == pytest.approx(math.radians(5.0), rel=1e-12)
    assert c.airdata.n_sigma == 3.0  # untouched keys keep their defaults


@pytest.mark.parametrize("name", ["weather_calm.toml", "weather_moderate_turbulence.toml"])
def test_shipped_weather_configs_load(name):
    from pathlib import Path

    p = Path(__file__).resolve().parents[3] / "configs" / name
    c = load_config(p)
    assert c.estimators.airdata == "cmhe"  # only the declared weather changes
    assert c.airdata.wind_mps > 0.0


def test_shipped_wan2018_transport_config_loads():
    from pathlib import Path

    c = load_config(Path(__file__).resolve().parents[3] / "configs" / "wan2018_transport.toml")
    assert c.fdi.aoa.threshold == pytest.approx(math.radians(0.902))
    assert c.airdata.lateral_terms is True  # calibrated with the default model
    assert c.fdi.cas.threshold > c.fdi.cas.threshold_per_turbulence == 0.0
    assert c.fdi.aoa.stuck_window_s == c.fdi.cas.no_data_window_s == 0.5
    assert c.estimators.airdata == "cmhe"


def test_shipped_wan2018_extensions_config_loads():
    from pathlib import Path

    from gcs_monitor.config import scheduled_threshold

    c = load_config(Path(__file__).resolve().parents[3] / "configs"
                    / "wan2018_transport_extensions.toml")
    assert c.fdi.aoa.threshold == pytest.approx(math.radians(0.327))
    assert scheduled_threshold(c.fdi.aoa, 3.6) == pytest.approx(math.radians(0.327 + 0.170 * 3.6))
    assert c.fdi.aoa.equal_pair_weights and c.fdi.cas.equal_pair_weights
    assert c.fdi.aoa.restart_peers and c.airdata.lateral_terms  # the defaults it was run with


def test_airdata_model_switch_reaches_the_estimator(tmp_path):
    from gcs_monitor.monitor import build_estimators

    c = load_config(_write(tmp_path, "[airdata]\nwind_accel_in_alpha = false\n"))
    assert c.airdata.wind_accel_in_alpha is False
    _, est = build_estimators(c)
    assert est.model.params.wind_accel_in_alpha is False  # Wan2018 eq. 13
    _, est_default = build_estimators(load_config(None))
    assert est_default.model.params.wind_accel_in_alpha is True


def test_stuck_window_reaches_the_set_monitor(tmp_path):
    from gcs_monitor.pipeline import AIR_DT_S, set_params

    c = load_config(_write(tmp_path,
                           "[fdi.cas]\nstuck_window_s = 0\n[fdi.aoa]\nstuck_window_s = 3\n"))
    assert set_params("cas", c.fdi.cas, AIR_DT_S).stuck_n == 0  # off: the Wan2018 scheme
    assert set_params("aoa", c.fdi.aoa, AIR_DT_S).stuck_n == 60  # 3 s at 20 Hz
    assert set_params("aoa", load_config(None).fdi.aoa, AIR_DT_S).stuck_n == 10  # default 0.5 s


def test_no_data_window_reaches_the_set_monitor(tmp_path):
    from gcs_monitor.pipeline import AIR_DT_S, set_params

    c = load_config(_write(tmp_path, "[fdi.cas]\nno_data_window_s = 0\n"
                                     "[fdi.aoa]\nno_data_window_s = 1.5\n"))
    assert set_params("cas", c.fdi.cas, AIR_DT_S).no_data_n == 0  # off
    assert set_params("aoa", c.fdi.aoa, AIR_DT_S).no_data_n == 30  # 1.5 s at 20 Hz
    assert set_params("cas", load_config(None).fdi.cas, AIR_DT_S).no_data_n == 10  # 0.5 s


def test_restart_peers_reaches_the_set_monitor(tmp_path):
    from gcs_monitor.pipeline import AIR_DT_S, set_params

    c = load_config(_write(tmp_path, "[fdi.aoa]\nrestart_peers = false\n"))
    assert not set_params("aoa", c.fdi.aoa, AIR_DT_S).restart_peers  # Wan2018's scheme
    assert set_params("cas", c.fdi.cas, AIR_DT_S).restart_peers  # default
    with pytest.raises(ConfigError, match="restart_peers"):
        load_config(_write(tmp_path, "[fdi.cas]\nrestart_peers = 1\n"))


def test_equal_pair_weights_reaches_the_fusion(tmp_path):
    from gcs_monitor.pipeline import VehiclePipeline

    assert not VehiclePipeline(1, load_config(None))._aoa_fusion.equal_pair  # off by default
    p = VehiclePipeline(1, load_config(_write(tmp_path, "[fdi.aoa]\nequal_pair_weights = true\n")))
    assert p._aoa_fusion.equal_pair and not p._cas_fusion.equal_pair
    with pytest.raises(ConfigError, match="equal_pair_weights"):
        load_config(_write(tmp_path, "[fdi.cas]\nequal_pair_weights = \"yes\"\n"))


def test_threshold_grows_with_the_declared_turbulence(tmp_path):
    from gcs_monitor.config import scheduled_threshold
    from gcs_monitor.core.units import DEG2RAD, KT2MPS
    from gcs_monitor.pipeline import VehiclePipeline

    c = load_config(_write(tmp_path, "[fdi.aoa]\nthreshold_deg = 0.5\n"
                                     "threshold_slope_deg_per_mps = 0.2\n"
                                     "[fdi.cas]\nthreshold_kts = 1.5\n"
                                     "threshold_slope_kts_per_mps = 1.0\n"
                                     "[airdata]\nturbulence_sigma_kts = 4\n"))
    sigma = 4 * KT2MPS
    assert c.airdata.turbulence_sigma_mps == pytest.approx(sigma)
    assert scheduled_threshold(c.fdi.aoa, sigma) == pytest.approx((0.5 + 0.2 * sigma) * DEG2RAD)
    # the pipeline's set monitors use the scheduled J_th
    p = VehiclePipeline(1, c)
    assert p.aoa_set.p.threshold == pytest.approx((0.5 + 0.2 * sigma) * DEG2RAD)
    assert p.cas_set.p.threshold == pytest.approx((1.5 + 1.0 * sigma) * KT2MPS)
    # no slope given: one fixed J_th (Wan2018), whatever the weather
    d = load_config(_write(tmp_path, "[airdata]\nturbulence_sigma_kts = 4\n"))
    assert VehiclePipeline(1, d).aoa_set.p.threshold == pytest.approx(d.fdi.aoa.threshold)
    with pytest.raises(ConfigError, match="threshold_slope_deg_per_mps"):
        load_config(_write(tmp_path, "[fdi.aoa]\nthreshold_slope_deg = 0.2\n"))


def test_lateral_terms_switch_reaches_the_estimator(tmp_path):
    from gcs_monitor.monitor import build_estimators

    c = load_config(_write(tmp_path, "[airdata]\nlateral_terms = false\n"))
    assert c.airdata.lateral_terms is False  # Wan2018's wings-level model
    _, est = build_estimators(c)
    assert est.cfg.lateral_terms is False
    _, est_default = build_estimators(load_config(None))
    assert est_default.cfg.lateral_terms is True  # the monitor's default: bank and sideslip
    from gcs_monitor.evaluation.configs import variant_config

    assert variant_config("cmhe").airdata.lateral_terms is False  # the paper reproductions
    assert variant_config("cmhe", lateral=True).airdata.lateral_terms is True
    paper = variant_config("cmhe")
    assert not paper.fdi.aoa.restart_peers and not paper.fdi.cas.restart_peers
    assert variant_config("cmhe", restart_peers=True).fdi.aoa.restart_peers
    assert not paper.fdi.aoa.equal_pair_weights and not paper.fdi.cas.equal_pair_weights
    assert variant_config("cmhe", equal_pair=True).fdi.cas.equal_pair_weights
    with pytest.raises(ConfigError, match="must be true or false"):
        load_config(_write(tmp_path, "[airdata]\nlateral_terms = 1\n"))
