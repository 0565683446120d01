"""Flight logs as MAVLink: formats, units and frames at the boundary, errors an operator can act
on. Runs on the vendored fixtures (tests/data/real) and on written DataFlash logs."""

from __future__ import annotations

import math
import os
import random
from pathlib import Path

import numpy as np
import pytest

from gcs_monitor.cli import main
from gcs_monitor.convert.csvmap import MAPS_DIR, read_mapped_csv
from gcs_monitor.convert.formats import read_onspeed
from gcs_monitor.convert.logbase import KNOWN_FORMATS, LogError
from gcs_monitor.convert.logs import detect_log_format
from gcs_monitor.link.decode import Decoder
from gcs_monitor.link.logs import open_log
from tests.helpers.dataflash import plane_log

DATA = Path(__file__).resolve().parents[2] / "data" / "real"


def _messages(path: Path, **kw) -> tuple[dict[str, list], object]:
    """Every decoded message of a log, by type, through the normal decode path."""
    opened = open_log(path, **kw)
    dec = Decoder()
    out: dict[str, list] = {}
    for data, wall in opened.source:
        for m in dec.feed(data, wall):
            out.setdefault(m.get_type(), []).append(m)
    return out, opened.info


@pytest.mark.parametrize("name, fmt", [
    ("pyulog_sample_appended_multiple.ulg", "ulog"), ("px4_sitl_current_topics.ulg", "ulog"),
    ("onspeed_vac_decel_10s.csv", "onspeed"), ("dronekit_copter_60s.tlog", "tlog")])
def test_detected_from_content(name: str, fmt: str, tmp_path: Path) -> None:
    assert detect_log_format(DATA / name) == fmt
    renamed = tmp_path / "flight.dat"  # the content decides, not the extension
    renamed.write_bytes((DATA / name).read_bytes())
    assert detect_log_format(renamed) == fmt


def test_dataflash_units_frames_instances(tmp_path: Path) -> None:
    m, info = _messages(plane_log(tmp_path / "plane.bin", seconds=10.0))
    assert info.fmt == "dataflash" and info.vehicle.startswith("ArduPlane")
    hb = m["HEARTBEAT"][0]
    assert hb.type == 1 and hb.autopilot == 3  # fixed wing, ArduPilot
    imu = m["HIGHRES_IMU"]
    assert {x.id for x in imu} == {0, 1}
    rate = (len([x for x in imu if x.id == 0]) - 1) / ((imu[-1].time_usec - imu[0].time_usec)
                                                       * 1e-6)
    assert 95.0 < rate < 105.0  # 200 Hz logged, block means at the default 100 Hz
    x = imu[0]
    np.testing.assert_allclose([x.xacc, x.yacc, x.zacc, x.xgyro, x.ygyro, x.zgyro],
                               [0.5, -0.2, -9.8, 0.01, -0.02, 0.03], atol=1e-6)  # float32
    att = m["ATTITUDE"][0]
    np.testing.assert_allclose([att.roll, att.pitch, att.yaw],
                               np.radians([2.0, 4.0, 45.0]), atol=1e-6)
    g = m["GLOBAL_POSITION_INT"][0]
    # 20 m/s on course 45 deg, 0.5 m/s climbing (VZ is NED down): cm/s
    assert (g.vx, g.vy, g.vz) == (1414, 1414, -50)
    assert abs(g.lat - 473000000) <= 1 and abs(g.alt - 500000) <= 10
    assert {a.id for a in m["AIRSPEED"]} == {0, 1} and m["AIRSPEED"][1].airspeed == 22.0
    assert abs(m["AOA_SSA"][0].AOA - 3.0) < 1e-6
    hud = m["VFR_HUD"][-1]
    assert abs(hud.airspeed - 21.5) < 1e-6  # CTUN's airspeed (ArduPlane's own)
    assert abs(hud.alt - 100.0) < 1.0  # ISA pressure altitude of 100129 Pa
    assert m["SERVO_OUTPUT_RAW"][0].servo2_raw == 1600
    nav = m["NAV_CONTROLLER_OUTPUT"][0]
    assert abs(nav.nav_roll - 5.0) < 1e-4 and nav.target_bearing == 90
    assert m["ATTITUDE_TARGET"]


def test_dataflash_text_log(tmp_path: Path) -> None:
    """The same flight as a text log (.log) reads the same."""
    from pymavlink import DFReader

    binp = plane_log(tmp_path / "plane.bin", seconds=3.0)
    r = DFReader.DFReader_binary(str(binp))
    lines = []
    while (msg := r.recv_msg()) is not None:
        if msg.get_type() == "FMT":
            lines.append(f"FMT, {msg.Type}, {msg.Length}, {msg.Name}, {msg.Format}, "
                         f"{msg.Columns}")
        else:
            vals = [str(getattr(msg, c)) for c in msg.get_fieldnames()]
            lines.append(", ".join([msg.get_type()] + vals))
    text = tmp_path / "plane.log"
    text.write_text("\n".join(lines) + "\n")
    assert detect_log_format(text) == "dataflash-text"
    mb, _ = _messages(binp)
    mt, info = _messages(text)
    assert info.fmt == "dataflash-text"
    assert len(mt["HIGHRES_IMU"]) == len(mb["HIGHRES_IMU"])
    assert mt["GLOBAL_POSITION_INT"][0].vx == mb["GLOBAL_POSITION_INT"][0].vx


def test_ulog_current_topics() -> None:
    m, info = _messages(DATA / "px4_sitl_current_topics.ulg")
    assert info.fmt == "ulog" and "PX4_SITL" in info.vehicle
    assert m["HEARTBEAT"][0].autopilot == 12  # MAV_AUTOPILOT_PX4
    acc = np.array([[x.xacc, x.yacc, x.zacc] for x in m["HIGHRES_IMU"]])
    assert abs(np.median(acc[:, 2]) + 9.8) < 0.5  # FRD specific force, z down, on the ground
    assert m["GLOBAL_POSITION_INT"] and m["GPS_RAW_INT"] and m["SCALED_PRESSURE"]
    p = np.median([x.press_abs for x in m["SCALED_PRESSURE"]])
    assert 900.0 < p < 1050.0  # hPa


def test_ulog_old_topics_without_gps_says_so() -> None:
    m, info = _messages(DATA / "pyulog_sample_appended_multiple.ulg")
    assert m["HIGHRES_IMU"] and m["ATTITUDE"] and m["SERVO_OUTPUT_RAW"]
    assert "GLOBAL_POSITION_INT" not in m
    assert any("no GPS velocity" in w for w in info.warnings)


def test_onspeed_gen2_headerless_map(tmp_path: Path) -> None:
    """The Gen2 layout without its header, through the shipped map, gives the OnSpeed IMU
    (read_onspeed's IMU 1) and its air data."""
    src = DATA / "onspeed_vac_decel_10s.csv"
    ref = read_onspeed(src)
    import csv

    with open(src, newline="") as fh:
        rows = list(csv.reader(fh))
    h = rows[0]
    order = ["timeStamp", "Pfwd", "PfwdSmoothed", "P45", "P45Smoothed", "PStatic", "Palt", "IAS",
             "AngleofAttack", "flapsPos", "DataMark", "OAT", "TAS", "imuTemp", "VerticalG",
             "LateralG", "ForwardG", "RollRate", "PitchRate", "YawRate", "Pitch", "Roll"]
    gen2 = tmp_path / "log_7.csv"
    with open(gen2, "w", newline="") as fh:
        w = csv.writer(fh)
        for r in rows[1:]:
            w.writerow([r[h.index(c)] if c in h else "0" for c in order])
    f = read_mapped_csv(gen2, MAPS_DIR / "onspeed_gen2.toml")
    np.testing.assert_allclose(f.acc_frd_mps2[0], ref.acc_frd_mps2[1], atol=1e-9)
    np.testing.assert_allclose(f.omega_frd_radps[0], ref.omega_frd_radps[1], atol=1e-9)
    np.testing.assert_allclose(f.cas_mps, ref.cas_mps, atol=1e-9)
    m, info = _messages(gen2, column_map=MAPS_DIR / "onspeed_gen2.toml")
    assert m["HIGHRES_IMU"] and m["AIRSPEED"] and m["AOA_SSA"] and info.fmt == "csvmap"


def test_zipline_map_matches_the_layout_reader(real_data_file) -> None:
    from gcs_monitor.convert.formats import read_zipline

    path = sorted(real_data_file("zipline_launch").glob("flight_*.csv"))[0]
    f = read_mapped_csv(path, MAPS_DIR / "zipline.toml")
    ref = read_zipline(path)
    np.testing.assert_allclose(f.acc_frd_mps2[0], ref.acc_frd_mps2[0])
    np.testing.assert_allclose(f.euler_rad, ref.euler_rad)


# -- bad files -----------------------------------------------------------------------------------
def _bad_files(tmp: Path) -> list[tuple[str, Path]]:
    good_bin = plane_log(tmp / "good.bin", seconds=4.0)
    ulg = (DATA / "px4_sitl_current_topics.ulg").read_bytes()
    rnd = random.Random(16)
    cases = {
        "empty .bin": ("empty.bin", b""),
        "empty .ulg": ("empty.ulg", b""),
        "truncated .bin (header only)": ("cut_header.bin", good_bin.read_bytes()[:700]),
        "truncated .bin (mid-record, half)": (
            "cut_half.bin", good_bin.read_bytes()[:len(good_bin.read_bytes()) // 2 + 7]),
        "truncated .ulg (header only)": ("cut_header.ulg", ulg[:2000]),
        "truncated .ulg (half)": ("cut_half.ulg", ulg[:len(ulg) // 2]),
        "wrong extension (.ulg that is a CSV)": (
            "flight.ulg", (DATA / "onspeed_vac_decel_10s.csv").read_bytes()[:20000]),
        "random bytes (.bin)": ("noise.bin", bytes(rnd.getrandbits(8) for _ in range(65536))),
        "text log (Paparazzi-style)": (
            "flight.tlog", b"".join(f"{k * 0.02:.3f} 1 ATTITUDE {k} 0.1 0.2\n".encode()
                                    for k in range(2000))),
    }
    out = []
    for label, (name, data) in cases.items():
        p = tmp / name
        p.write_bytes(data)
        out.append((label, p))
    return out


def test_bad_files_one_line_and_exit_codes(tmp_path: Path, capsys) -> None:
    """Each bad file: one line naming it and what was expected; exit 2 (unusable) or 3 (read in
    part). ``GCS_BAD_FILES_TABLE=path`` writes the table pasted in docs/results.md."""
    rows = []
    for label, path in _bad_files(tmp_path):
        rc = main(["replay", "--quiet", str(path)])
        err = capsys.readouterr().err.strip().splitlines()
        first = err[0] if err else ""
        assert str(path) in first, (label, err)
        if label.startswith("wrong extension"):
            assert rc == 0 and "named .ulg but the content is" in first, (label, rc, first)
        elif rc == 2:
            assert KNOWN_FORMATS in first or "needs IMU" in first or "without IMU" in first \
                or "no vehicle" in first, (label, first)
        else:
            assert rc == 3 and "incomplete record" in first, (label, rc, first)
        rows.append((label, rc, first.replace(str(tmp_path) + "/", "")))
    assert {r[1] for r in rows} <= {0, 2, 3}
    # a batch goes on past the bad files and lists them at the end
    good = plane_log(tmp_path / "good2.bin", seconds=4.0)
    bad = [p for _, p in _bad_files(tmp_path / "x" if (tmp_path / "x").mkdir() is None
                                     else tmp_path)][:2]
    rc = main(["replay", "--quiet", str(bad[0]), str(good), str(bad[1])])
    cap = capsys.readouterr()
    assert rc == 2 and "2 of 3 files could not be used" in cap.err and "good2.bin" in cap.out
    table = os.environ.get("GCS_BAD_FILES_TABLE")
    if table:
        lines = ["| file | exit code | message |", "|---|---|---|"]
        lines += [f"| {label} | {rc} | `{msg}` |" for label, rc, msg in rows]
        Path(table).write_text("\n".join(lines) + "\n")


def test_log_error_is_one_line(tmp_path: Path) -> None:
    p = tmp_path / "x.bin"
    p.write_bytes(b"")
    with pytest.raises(LogError) as exc:
        detect_log_format(p)
    assert "\n" not in str(exc.value) and str(p) in str(exc.value)
    assert not math.isnan(0.0)
