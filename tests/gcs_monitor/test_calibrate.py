"""gcs-monitor calibrate on simulated fault-free flights: the noise model recovers the simulated
sensor noise, J_th is the margin times the largest fault-free J, and the written configuration
loads and keeps the flights silent."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import pytest

from gcs_monitor.calibrate import calibrate, calibration_toml
from gcs_monitor.cli import main
from gcs_monitor.config import MonitorConfig, load_config
from gcs_monitor.core.units import DEG2RAD
from gcs_monitor.fdi.events import AlarmKind
from gcs_monitor.link.transports import TlogSource
from gcs_monitor.monitor import Monitor


@pytest.fixture(scope="module")
def flights(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    """Two fault-free 20 s flights of the demo airframe (triplex air data, three IMUs)."""
    from sim_vehicle.run import run_scenario
    from sim_vehicle.scenario import load_scenario

    out = tmp_path_factory.mktemp("flights")
    paths = []
    for seed in (3, 4):
        sc = dataclasses.replace(load_scenario("demo_airdata_faults"), faults=(),
                                 duration_s=20.0, seed=seed)
        res = run_scenario(sc, out, progress=False)
        assert res.tlog_path is not None
        paths.append(res.tlog_path)
    return paths


def test_noise_and_thresholds(flights: list[Path]) -> None:
    cal = calibrate(flights)
    # Lu2016 Table 1, the simulator's sensors: 0.1 deg vanes, 0.1 m/s pitots: the MAD of the
    # instance differences recovers them within 20 %. The accelerometer's first differences
    # also carry the demo's 1 m/s Dryden gusts (specific force changing from sample to sample):
    # the effective noise is above Table 1's 0.01 m/s^2 (0.015 measured) and below 2x it
    assert cal.noise["aoa"] == pytest.approx(0.1 * DEG2RAD, rel=0.2)
    assert cal.noise["cas"] == pytest.approx(0.1, rel=0.2)
    assert 0.01 <= cal.noise["acc"] < 0.02
    for key, th in cal.thresholds.items():
        worst = max(st.j_max[key] for st in cal.flights if key in st.j_max)
        assert th == pytest.approx(1.5 * worst, rel=1e-12)
    air = cal.config.family("airdata").fdi
    assert air.aoa.threshold == cal.thresholds["airdata.aoa"]


def test_cli_writes_a_config_that_keeps_the_flights_silent(flights: list[Path],
                                                            tmp_path: Path) -> None:
    out = tmp_path / "airframe.toml"
    assert main(["calibrate", *map(str, flights), "--out", str(out)]) == 0
    text = out.read_text()
    assert "[airdata.fdi.aoa]" in text and "threshold_deg" in text
    cfg = load_config(out)
    assert cfg != MonitorConfig()
    for path in flights:
        mon = Monitor(cfg)
        for data, wall in TlogSource(path):
            mon.feed(data, wall)
        mon.finish()
        assert [e for e in mon.events if e.kind in (AlarmKind.SENSOR_FAULT,
                                                     AlarmKind.SET_LOST)] == []


def test_calibration_toml_lists_only_changes(flights: list[Path]) -> None:
    cal = calibrate(flights[:1])
    text = calibration_toml(cal, MonitorConfig(), flights[:1])
    assert "[telemetry]" not in text and "[sinks]" not in text
    assert math.isfinite(cal.thresholds["airdata.cas"])


def test_bad_input() -> None:
    with pytest.raises(ValueError, match="at least one flight"):
        calibrate([])
    with pytest.raises(ValueError, match="margin"):
        calibrate([Path("x.tlog")], margin=1.0)
