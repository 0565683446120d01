"""Monitor config: defaults, unit conversion at load, the family sections reaching their code,
the printed defaults, and one focused test per validation rule."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import pytest

from gcs_monitor.config import ConfigError, MonitorConfig, config_toml, load_config
from gcs_monitor.core.units import DEG2RAD, KT2MPS
from gcs_monitor.families.airdata.family import AirDataFamily
from gcs_monitor.families.base import FamilyContext
from gcs_monitor.families.imu.family import ImuFamily
from gcs_monitor.fdi.config import scheduled_threshold, set_params
from gcs_monitor.pipeline import build_families
from gcs_monitor.telemetry.frame import Frame

CONFIGS = Path(__file__).resolve().parents[3] / "configs"
AIR_PERIOD_S = 0.05  # 20 Hz air data


def _write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "monitor.toml"
    p.write_text(text)
    return p


def _air(c: MonitorConfig) -> AirDataFamily:
    (fam,) = [f for f in build_families(dict(c.families), FamilyContext(1, 0.5))
              if isinstance(f, AirDataFamily)]
    return fam


def _air_sets(c: MonitorConfig) -> AirDataFamily:
    """The air-data family after its first 20 Hz sample (the set monitors exist)."""
    fam = _air(c)
    fr = Frame(t_us=0, imu=[None], air_new=True, air_period_s=AIR_PERIOD_S)
    fam.judge(fr, None)
    return fam


def test_defaults_run_without_a_file() -> None:
    c = load_config(None)
    assert c == MonitorConfig()
    aoa = c.family("airdata").fdi.aoa
    assert set_params(aoa, AIR_PERIOD_S).rms.rms_window_n == 10  # Wan2018: N_eval = 10
    assert c.family("airdata").estimator == "cmhe"
    assert c.family("imu").ts.enabled and not c.family("imu").hosm.enabled


def test_printed_defaults_load_back_bit_for_bit(tmp_path: Path) -> None:
    # `gcs-monitor config --defaults` output is a valid config equal to the defaults
    text = config_toml()
    assert load_config(_write(tmp_path, text)) == MonitorConfig()
    # every key carries a comment
    keys = [ln for ln in text.splitlines() if "=" in ln and not ln.startswith("#")]
    assert keys and all("  # " in ln for ln in keys)


def test_a_changed_config_prints_and_loads_back(tmp_path: Path) -> None:
    c = load_config(_write(tmp_path, "[airdata.fdi.aoa]\nthreshold_deg = 0.327\n"
                                     "[airdata.weather]\nturbulence_sigma_kts = 5\n"
                                     "[imu.hosm]\nenabled = true\n"))
    assert load_config(_write(tmp_path, config_toml(c, comments=False))) == c


def test_units_converted_once(tmp_path: Path) -> None:
    c = load_config(_write(tmp_path, "[airdata.fdi.aoa]\nthreshold_deg = 2.0\n"
                                     "[airdata.fdi.cas]\nthreshold_kts = 10\n"))
    fdi = c.family("airdata").fdi
    assert fdi.aoa.threshold == pytest.approx(math.radians(2.0), rel=1e-12)
    assert fdi.cas.threshold == pytest.approx(10 * 1852 / 3600, rel=1e-12)


def test_imu_hosm_thresholds_are_their_own_keys(tmp_path: Path) -> None:
    c = load_config(_write(tmp_path, "[imu.hosm]\nenabled = true\n"
                           "[imu.hosm.fdi.acc]\nthreshold_mps2 = 0.9\n"
                           "[imu.hosm.fdi.gyro]\nthreshold_degps = 0.8\n"))
    imu = c.family("imu")
    assert imu.hosm.enabled
    assert imu.hosm.fdi.acc.threshold == pytest.approx(0.9, rel=1e-12)
    assert imu.hosm.fdi.gyro.threshold == pytest.approx(math.radians(0.8), rel=1e-12)
    # the ATSEKF thresholds are untouched
    assert imu.ts.fdi.acc.threshold == MonitorConfig().family("imu").ts.fdi.acc.threshold


def test_estimator_parameters_are_reachable(tmp_path: Path) -> None:
    # parameters the monitor used to build with its defaults only now come from the file
    c = load_config(_write(tmp_path, "[imu.ts.estimator]\nmax_dt_s = 0.5\n"
                                     "[imu.ts.estimator.noise]\nacc_sigma_mps2 = 0.05\n"
                                     "[imu.ts.estimator.gate]\nmax_rejected_n = 7\n"
                                     "[imu.ts.estimator.filter]\nwindow_n = 20\n"
                                     "[airdata.filter]\nq_w_m2ps4 = 9\n"))
    fams = build_families(dict(c.families), FamilyContext(1, 0.5))
    imu = next(f for f in fams if isinstance(f, ImuFamily))
    ts = imu.estimators[0].cfg  # type: ignore[attr-defined]
    assert (ts.max_dt_s, ts.noise.acc_sigma_mps2, ts.gate.max_rejected_n, ts.filter.window_n) \
        == (0.5, 0.05, 7, 20)
    air = next(f for f in fams if isinstance(f, AirDataFamily))
    assert air.estimator is not None and air.estimator.cfg.q_w_m2ps4 == 9.0


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("[nope]\n", r"unknown section \[nope\]"),
        ("[fdi.aoa]\nthreshold_deg = 1\n", r"unknown section \[fdi\] \(the FDI sets moved"),
        ("[estimators]\nimu_hosm = true\n", r"estimators are chosen per family"),
        ("[sinks]\nrerun_hz = 3\n", r"unknown key 'sinks.rerun_hz'"),
        ("[airdata.fdi.aoa]\nthreshold_kts = 3\n", r"unknown key 'airdata.fdi.aoa.threshold_kts'"),
        ("[airdata.fdi.aoa]\nn_eval = 10\n", r"windows are in seconds now"),
        ("[airdata.fdi.aoa]\ndetect_ratio = 1.5\n", r"detect_ratio must be in \(0, 1\]"),
        ("[airdata]\nestimator = 'kalman'\n", r"must be one of"),
        ("[telemetry]\ngps_delay_s = 'x'\n", r"'telemetry.gps_delay_s' must be a number"),
        ("[airdata.fdi]\nbaro = {}\n", r"unknown key 'airdata.fdi.baro'"),
        ("x = [", r"not valid TOML"),
        ("[imu.hosm.fdi.gyro]\nthreshold_mps2 = 0.5\n", r"expected one of .*'threshold_degps'"),
        ("[imu.hosm.fdi.acc]\nthreshold_mps2 = -1\n",
         r"'imu.hosm.fdi.acc.threshold_mps2' must be a positive"),
        ("[airdata.fdi.aoa]\nstuck_window_s = 0.1\n", r"stuck_window_s must be 0 \(off\)"),
        ("[airdata.fdi.cas]\nno_data_window_s = -1\n",
         r"'airdata.fdi.cas.no_data_window_s' must be a non-negative number"),
        ("[airdata]\nwind_kts = 3\n", r"moved to \[airdata.weather\]"),
        ("[airdata.weather]\nturbulence_sigma_kts = -1\n", r"must be a non-negative number"),
        ("[airdata.filter]\nwind_accel_in_alpha = 1\n", r"must be true or false"),
        ("[airdata]\nlateral_terms = false\n", r"moved to \[airdata.filter\]"),
        ("[imu.hosm.estimator.levant]\nk = [1.0, 2.0]\n", r"must have 4 elements"),
        ("[imu.ts.estimator]\nmodel = 'xy'\n", r"must be one of \['gs', 'as'\]"),
        ("[imu]\nts = 3\n", r"\[imu.ts\] must be a table"),
    ],
)
def test_invalid_config_names_file_and_key(tmp_path: Path, text: str, match: str) -> None:
    p = _write(tmp_path, text)
    with pytest.raises(ConfigError, match=match) as ei:
        load_config(p)
    assert str(p) in str(ei.value)


def test_missing_file_is_a_config_error(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="no such config file"):
        load_config(tmp_path / "absent.toml")


def test_shipped_imu_hosm_config_loads() -> None:
    c = load_config(CONFIGS / "imu_hosm.toml")
    imu = c.family("imu")
    assert imu.hosm.enabled and not imu.ts.enabled
    assert imu.hosm.fdi.acc.threshold == MonitorConfig().family("imu").hosm.fdi.acc.threshold


def test_weather_in_knots(tmp_path: Path) -> None:
    """[airdata.weather]: the declared weather, knots in the file, SI after loading."""
    c = load_config(_write(tmp_path, "[airdata.weather]\nwind_kts = 30\n"
                                     "turbulence_sigma_kts = 4\nshear_rate_ktsps = 2\n"
                                     "flight_path_max_deg = 5\n"))
    w = c.family("airdata").weather
    kt = 1852 / 3600
    assert w.wind_mps == pytest.approx(30 * kt, rel=1e-12)
    assert w.turbulence_sigma_mps == pytest.approx(4 * kt, rel=1e-12)
    assert w.shear_rate_mps2 == pytest.approx(2 * kt, rel=1e-12)
    assert w.flight_path_max_rad == pytest.approx(math.radians(5.0), rel=1e-12)
    assert w.n_sigma == 3.0  # untouched keys keep their defaults


@pytest.mark.parametrize("name", ["weather_calm.toml", "weather_moderate_turbulence.toml"])
def test_shipped_weather_configs_load(name: str) -> None:
    c = load_config(CONFIGS / name)
    assert c.family("airdata").estimator == "cmhe"  # only the declared weather changes
    assert c.family("airdata").weather.wind_mps > 0.0


def test_shipped_wan2018_transport_config_loads() -> None:
    c = load_config(CONFIGS / "wan2018_transport.toml")
    air = c.family("airdata")
    assert air.fdi.aoa.threshold == pytest.approx(math.radians(0.902))
    assert air.filter.lateral_terms is True  # calibrated with the default model
    assert air.fdi.cas.threshold > air.fdi.cas.threshold_per_turbulence == 0.0
    assert air.fdi.aoa.stuck_window_s == air.fdi.cas.no_data_window_s == 0.5
    assert air.estimator == "cmhe"


def test_shipped_wan2018_extensions_config_loads() -> None:
    c = load_config(CONFIGS / "wan2018_transport_extensions.toml")
    fdi = c.family("airdata").fdi
    assert fdi.aoa.threshold == pytest.approx(math.radians(0.327))
    assert scheduled_threshold(fdi.aoa, 3.6) == pytest.approx(math.radians(0.327 + 0.170 * 3.6))
    assert fdi.aoa.equal_pair_weights and fdi.cas.equal_pair_weights
    assert fdi.aoa.restart_peers and c.family("airdata").filter.lateral_terms


def test_airdata_model_switches_reach_the_estimator(tmp_path: Path) -> None:
    c = load_config(_write(tmp_path, "[airdata.filter]\nwind_accel_in_alpha = false\n"
                                     "lateral_terms = false\n"))
    est = _air(c).estimator
    assert est is not None
    assert est.model.params.wind_accel_in_alpha is False  # Wan2018 eq. 13
    assert est.cfg.lateral_terms is False  # Wan2018's wings-level model
    default = _air(MonitorConfig()).estimator
    assert default is not None
    assert default.model.params.wind_accel_in_alpha is True
    assert default.cfg.lateral_terms is True  # the monitor's default: bank and sideslip
    assert default.cfg.envelope == MonitorConfig().family("airdata").weather


def test_windows_in_seconds_reach_the_set_monitor(tmp_path: Path) -> None:
    c = load_config(_write(tmp_path, "[airdata.fdi.cas]\nstuck_window_s = 0\n"
                                     "no_data_window_s = 0\n"
                                     "[airdata.fdi.aoa]\nstuck_window_s = 3\n"
                                     "no_data_window_s = 1.5\nrestart_peers = false\n"))
    sets = _air_sets(c).sets
    assert sets["cas"].p.stuck_n == 0 and sets["cas"].p.no_data_n == 0  # off
    assert sets["aoa"].p.stuck_n == 60  # 3 s at 20 Hz
    assert sets["aoa"].p.no_data_n == 30  # 1.5 s at 20 Hz
    assert not sets["aoa"].p.restart_peers and sets["cas"].p.restart_peers
    d = _air_sets(MonitorConfig()).sets
    assert d["aoa"].p.stuck_n == 10 and d["cas"].p.no_data_n == 10  # default 0.5 s


def test_windows_follow_the_measured_air_data_rate() -> None:
    # 0.5 s is N_eval = 10 samples at 20 Hz (Wan2018) and 25 at 50 Hz
    fam = _air(MonitorConfig())
    fam.judge(Frame(t_us=0, imu=[None], air_new=True, air_period_s=0.02), None)
    assert fam.sets["aoa"].p.rms.rms_window_n == 25
    assert fam.sets["aoa"].p.no_data_n == 25 and fam.sets["aoa"].p.dt_s == 0.02


def test_air_data_is_not_judged_before_its_period_is_known() -> None:
    fam = _air(MonitorConfig())
    v = fam.judge(Frame(t_us=0, imu=[None], air_new=True), None)
    assert not v.status.judged and "period" in v.status.reason and not fam.sets


def test_equal_pair_weights_reaches_the_fusion(tmp_path: Path) -> None:
    assert not _air_sets(MonitorConfig())._fusion["aoa"].equal_pair  # off by default
    fam = _air_sets(load_config(_write(tmp_path,
                                       "[airdata.fdi.aoa]\nequal_pair_weights = true\n")))
    assert fam._fusion["aoa"].equal_pair and not fam._fusion["cas"].equal_pair
    with pytest.raises(ConfigError, match="equal_pair_weights"):
        load_config(_write(tmp_path, "[airdata.fdi.cas]\nequal_pair_weights = \"yes\"\n"))


def test_threshold_grows_with_the_declared_turbulence(tmp_path: Path) -> None:
    # the declared weather alone (no online estimate, as Wan2018)
    c = load_config(_write(tmp_path, "[airdata.fdi.aoa]\nthreshold_deg = 0.5\n"
                                     "threshold_slope_deg_per_mps = 0.2\n"
                                     "[airdata.fdi.cas]\nthreshold_kts = 1.5\n"
                                     "threshold_slope_kts_per_mps = 1.0\n"
                                     "[airdata.weather]\nturbulence_sigma_kts = 4\n"
                                     "[airdata.weather_estimate]\nenabled = false\n"))
    sigma = 4 * KT2MPS
    air = c.family("airdata")
    assert air.weather.turbulence_sigma_mps == pytest.approx(sigma)
    assert scheduled_threshold(air.fdi.aoa, sigma) == pytest.approx((0.5 + 0.2 * sigma) * DEG2RAD)
    # the family's set monitors use the scheduled J_th
    sets = _air_sets(c).sets
    assert sets["aoa"].p.threshold == pytest.approx((0.5 + 0.2 * sigma) * DEG2RAD)
    assert sets["cas"].p.threshold == pytest.approx((1.5 + 1.0 * sigma) * KT2MPS)
    # with the online estimate, J_th follows the start prior until it has converged
    e = load_config(_write(tmp_path, "[airdata.fdi.aoa]\nthreshold_deg = 0.5\n"
                                     "threshold_slope_deg_per_mps = 0.2\n"))
    start = e.family("airdata").weather_estimate.start_sigma_mps
    assert _air_sets(e).sets["aoa"].p.threshold == pytest.approx((0.5 + 0.2 * start) * DEG2RAD)
    # no slope given: one fixed J_th (Wan2018), whatever the weather
    d = load_config(_write(tmp_path, "[airdata.weather]\nturbulence_sigma_kts = 4\n"))
    assert _air_sets(d).sets["aoa"].p.threshold == pytest.approx(
        d.family("airdata").fdi.aoa.threshold)


def test_with_family_replaces_one_family() -> None:
    c = MonitorConfig().with_family("airdata", estimator="none")
    assert c.family("airdata").estimator == "none"
    assert c.family("imu") == MonitorConfig().family("imu")
    imu = dataclasses.replace(c.family("imu"), enabled=False)
    assert [f.name for f in build_families(dict(c.with_family("imu", imu).families),
                                           FamilyContext(1, 0.5))] == ["airdata", "yaw_rate",
                                                                       "actuators"]
