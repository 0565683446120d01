"""gcs-monitor calibrate on simulated fault-free flights: the noise model recovers the simulated
sensor noise, J_th is the margin times the largest fault-free J, the yaw-rate family's lateral
model is identified (or the missing input named), and the written configuration loads and keeps
the flights silent."""

from __future__ import annotations

import contextlib
import dataclasses
import io
import json
import math
import re
from pathlib import Path

import pytest

from gcs_monitor.calibrate import (
    Calibration,
    FlightPart,
    FlightStats,
    calibrate,
    calibration_toml,
    margins_table,
    parse_flight,
    spike_warnings,
)
from gcs_monitor.cli import main
from gcs_monitor.config import MonitorConfig, load_config
from gcs_monitor.core.units import DEG2RAD
from gcs_monitor.families.yaw_rate.design import load_design
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


@pytest.fixture(scope="module")
def calibrated(flights: list[Path], tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """``gcs-monitor calibrate`` on both flights: the written TOML and what it printed."""
    out = tmp_path_factory.mktemp("cal") / "airframe.toml"
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert main(["calibrate", *map(str, flights), "--out", str(out)]) == 0
    return out, buf.getvalue()


def test_cli_writes_a_config_that_keeps_the_flights_silent(flights: list[Path],
                                                            calibrated: tuple[Path, str]) -> None:
    out, _ = calibrated
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


def test_cli_identifies_the_yaw_rate_model_and_replay_judges_with_it(
        flights: list[Path], calibrated: tuple[Path, str]) -> None:
    out, printed = calibrated
    design = out.parent / "airframe.yaw_rate.json"
    cfg = load_config(out)
    assert Path(cfg.family("yaw_rate").design).resolve() == design.resolve()
    # named relative to the TOML: the two files move together
    assert 'design = "airframe.yaw_rate.json"' in out.read_text()
    moved = out.parent / "moved"
    moved.mkdir(exist_ok=True)
    for f in (out, design):
        (moved / f.name).write_bytes(f.read_bytes())
    assert load_config(moved / out.name).family("yaw_rate").design == str(
        moved / design.name)
    d = load_design(cfg.family("yaw_rate").design)
    # the demo flies one speed (250 kt at 3000 m): a constant model, said to be valid only there
    lo, hi = d.model.eas_range_mps
    assert 100.0 < lo < hi < 120.0  # m/s: EAS of 250 kt TAS at 3000 m +- the turbulence
    assert not d.model.A[1:].any() and not d.model.B[1:].any()
    assert "a constant model, valid only near that speed" in printed
    assert f"EAS {lo:.1f}-{hi:.1f} m/s" in printed
    # and judged there only: 5 % margin ([yaw_rate.observer] eas_margin)
    assert f"judges only at EAS {0.95 * lo:.1f}-{1.05 * hi:.1f} m/s" in printed
    # the fit error printed is the design's
    m = re.search(r"fit error \(derivative NRMSE\): phi (\S+), beta (\S+), p (\S+), r (\S+)",
                  printed)
    assert m is not None
    nrmse = json.loads(design.read_text())["meta"]["fit"]["nrmse"]
    assert [float(v) for v in m.groups()] == pytest.approx(nrmse, rel=1e-2)  # 3 digits printed
    # the yaw-rate J_th comes from the second pass on the new design
    th = cfg.family("yaw_rate").fdi.threshold
    assert th != MonitorConfig().family("yaw_rate").fdi.threshold
    judged = []
    mon = Monitor(cfg, on_step=lambda sysid, frame, step: judged.extend(
        f.judged for f in step.families if f.family == "yaw_rate" and f.sample))
    for data, wall in TlogSource(flights[0]):
        mon.feed(data, wall)
    mon.finish()
    # judged after the 2 s warm-up over the rest of the 20 s flight
    assert 0.8 < sum(judged) / len(judged) < 1.0
    assert not [e for e in mon.events if e.estimator == "yaw_rate_smo"]


def _without_message(src: Path, dst: Path, msg_id: int) -> Path:
    """A copy of the .tlog ``src`` (8-byte timestamp + unsigned MAVLink 2 packet per record)
    without the packets of message ``msg_id``."""
    data = src.read_bytes()
    keep = []
    i = 0
    while i < len(data):
        assert data[i + 8] == 0xFD  # MAVLink 2 start byte
        n = 8 + 12 + data[i + 9] + (13 if data[i + 10] & 1 else 0)
        if int.from_bytes(data[i + 15:i + 18], "little") != msg_id:
            keep.append(data[i:i + n])
        i += n
    dst.write_bytes(b"".join(keep))
    return dst


def test_cli_names_the_missing_input_and_keeps_the_shipped_design(flights: list[Path],
                                                                  tmp_path: Path) -> None:
    flight = _without_message(flights[0], tmp_path / "no_ssa.tlog", 11020)  # AOA_SSA
    out = tmp_path / "airframe.toml"
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert main(["calibrate", str(flight), "--out", str(out)]) == 0
    assert ("yaw_rate: lateral model NOT identified: the flights carry no sideslip (AOA_SSA); "
            "the family keeps its shipped design 'transport'") in buf.getvalue()
    assert not (tmp_path / "airframe.yaw_rate.json").exists()
    assert load_config(out).family("yaw_rate").design == "transport"


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


def test_flight_windows_parse() -> None:
    assert parse_flight("a.tlog") == FlightPart(Path("a.tlog"))
    assert parse_flight("logs/a.bin@60:190") == FlightPart(Path("logs/a.bin"), 60.0, 190.0)
    part = parse_flight("a.bin@:190.5")
    assert (part.t0_s, part.t1_s) == (-math.inf, 190.5)
    assert part.name == "a.bin@:190.5"
    assert parse_flight("a.bin@60:").name == "a.bin@60:"
    assert not parse_flight("a.bin").windowed and parse_flight("a.bin@60:").windowed
    assert parse_flight("a.bin@60:").covers(61_000_000)
    assert not parse_flight("a.bin@60:").covers(59_999_999)
    for bad, why in (("a.bin@60", "expected PATH@T0:T1"), ("a.bin@x:3", "expected PATH@T0:T1"),
                     ("a.bin@90:60", "not before its end")):
        with pytest.raises(ValueError, match=why):
            parse_flight(bad)


def test_a_file_whose_name_has_an_at_sign_is_a_flight(tmp_path: Path) -> None:
    f = tmp_path / "run@1:2.tlog"
    f.write_bytes(b"")
    assert parse_flight(str(f)) == FlightPart(f)


def test_a_window_learns_from_its_part_of_the_flight_only(flights: list[Path]) -> None:
    whole = calibrate(flights[:1]).flights[0]
    part = calibrate([FlightPart(flights[0], 12.0, 16.0)]).flights[0]
    assert part.name == f"{flights[0].name}@12:16"
    for key, t in part.j_at_s.items():
        assert 12.0 <= t <= 16.0, key
        # the window's largest J is the whole flight's largest within it, not above it
        assert part.j_max[key] <= whole.j_max[key] * (1.0 + 1e-12)
        assert 0.0 < part.j_p95[key] <= part.j_max[key]
    assert part.j_at_s.keys() == whole.j_at_s.keys()


def test_a_moment_far_above_the_rest_of_its_flight_is_named() -> None:
    st = FlightStats("crash.bin", 300.0, j_max={"imu.ts.gyro": 0.76, "imu.ts.acc": 4.9},
                     j_at_s={"imu.ts.gyro": 52.3, "imu.ts.acc": 50.9},
                     j_p95={"imu.ts.gyro": 0.06, "imu.ts.acc": 2.1})
    assert st.spikes() == {"imu.ts.gyro": pytest.approx(0.76 / 0.06)}  # acc: 2.3 x, a floor
    cal = Calibration(MonitorConfig(), {}, {"imu.ts.gyro": 1.5 * 0.76, "imu.ts.acc": 1.5 * 4.9},
                      [st], 1.5)
    (line,) = spike_warnings(cal)
    assert line.startswith("warning: crash.bin: the largest imu.ts.gyro J (0.76, at 52.3 s) is "
                           "12.7 x the flight's 95th percentile (0.06): it sets that J_th.")
    assert "FLIGHT@T0:T1" in line
    assert ("| crash.bin | 300 | 0.67 at 50.9 s (p95 0.29) | 0.67 at 52.3 s (p95 0.05) |"
            in margins_table(cal))


def test_cli_takes_a_window_and_says_when_each_largest_j_came(flights: list[Path],
                                                              tmp_path: Path) -> None:
    out = tmp_path / "airframe.toml"
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert main(["calibrate", f"{flights[0]}@5:", "--out", str(out)]) == 0
    printed = buf.getvalue()
    assert f"| {flights[0].name}@5: | 20 |" in printed
    assert re.search(r"\| 0\.67 at ([0-9.]+) s \(p95 0\.[0-9]{2}\) \|", printed)
    assert f"#   {flights[0].name}@5:" in out.read_text()
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        assert main(["calibrate", f"{flights[0]}@9:5", "--out", str(out)]) == 2
    assert "not before its end" in err.getvalue()
