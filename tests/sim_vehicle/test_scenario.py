"""Scenario TOML: strict validation, unit conversion, presets, serialisation round trip."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from gcs_monitor.core.units import DEG2RAD, KT2MPS
from sim_vehicle.scenario import (
    ScenarioError,
    list_presets,
    load_scenario,
    parse_scenario,
    to_toml,
)

BASE = """
[scenario]
airframe = "transport"
duration_s = 20.0
seed = 5
[sensors]
n_imu = 2
"""


def fault(body: str) -> str:
    return BASE + "\n[[faults]]\n" + body


def test_units_converted_to_si() -> None:
    sc = parse_scenario(BASE + """
[initial]
tas_kts = 250.0
alt_ft = 10000.0
[[faults]]
channel = "aoa1"
kind = "bias"
t_start_s = 2.0
bias_deg = 3.0
[[faults]]
channel = "cas2"
kind = "runaway"
t_start_s = 5.0
rate_kts_per_s = -15.0
limit_kts = 40.0
""", "x.toml")
    assert sc.initial.tas_mps == pytest.approx(250 * KT2MPS)
    assert sc.initial.alt_m == pytest.approx(3048.0)
    assert sc.faults[0].get("bias") == pytest.approx(3 * DEG2RAD)
    assert dict(sc.faults[0].params) == {"bias_rad": pytest.approx(3 * DEG2RAD)}
    assert sc.faults[1].get("rate") == pytest.approx(-15 * KT2MPS)
    assert sc.faults[1].get("limit") == pytest.approx(40 * KT2MPS)


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        (BASE + "[wind]\nkindd = 'calm'\n", "key 'kindd': unknown key"),
        (fault('channel="aoa1"\nkind="bias"\nt_start_s=1.0\nbias_mps2=1.0'), "bias_deg"),
        (fault('channel="imu2.acc.x"\nkind="bias"\nt_start_s=1.0\nbias_mps2=1.0'), "no channel"),
        (fault('channel="cas0"\nkind="drift"\nt_start_s=1.0\nrate_kts=1.0'), "rate_kts_per_s"),
        (fault('channel="cas0"\nkind="bias"\nt_start_s=1.0'), "missing required key bias_"),
        (fault('channel="cas0"\nkind="wobble"\nt_start_s=1.0'), "key 'kind'"),
        (fault('channel="cas0"\nkind="bias"\nt_start_s=5.0\nt_end_s=2.0\nbias_kts=1.0'),
         "t_end_s"),
        (fault('channel="cas0"\nkind="expr"\nt_start_s=1.0\nexpr_kts="import os"'), "expr_kts"),
        (fault('channel="cas0"\nkind="nrz"\nt_start_s=1.0\nlevel=0.1\ngain=0.1'), "not both"),
        (BASE.replace('"transport"', '"concorde"'), "key 'airframe'"),
        (BASE + "[sensors2]\n", "unknown section"),
        (BASE.replace("n_imu = 2", "n_imu = 4"), "key 'n_imu'"),
        (BASE.replace("n_imu = 2", "n_imu = 2\ngps_hz = 20.0"), "key 'gps_hz'"),
        (BASE + "[initial]\ntas_knots = 200.0\n", "tas_mps"),
    ],
)
def test_validation_errors_name_file_and_key(text: str, needle: str) -> None:
    with pytest.raises(ScenarioError) as e:
        parse_scenario(text, "bad.toml")
    assert "bad.toml" in str(e.value)
    assert needle in str(e.value)


def test_overlapping_contradictory_faults_rejected() -> None:
    two = fault('channel="aoa0"\nkind="bias"\nt_start_s=1.0\nt_end_s=10.0\nbias_deg=1.0') + (
        '\n[[faults]]\nchannel="aoa0"\nkind="jam"\nt_start_s=5.0\n')
    with pytest.raises(ScenarioError, match="overlaps"):
        parse_scenario(two, "o.toml")
    # same kind back to back (no overlap) and bias + noise together are fine
    ok = fault('channel="aoa0"\nkind="bias"\nt_start_s=1.0\nt_end_s=5.0\nbias_deg=1.0') + (
        '\n[[faults]]\nchannel="aoa0"\nkind="bias"\nt_start_s=5.0\nbias_deg=2.0\n'
        '\n[[faults]]\nchannel="aoa0"\nkind="noise"\nt_start_s=2.0\nsigma_deg=1.0\n')
    assert len(parse_scenario(ok, "ok.toml").faults) == 3


def test_all_presets_load_and_round_trip() -> None:
    presets = dict(list_presets())
    for name in ("lu2016_calm", "lu2016_shear", "lu2016_turbulence", "lu2016_parabolic",
                 "atmaca2025_acc", "atmaca2025_gyro", "chen2020_fault_free",
                 "chen2020_slow_drift", "chen2020_fast_drift", "chen2020_sine",
                 "demo_airdata_faults", *(f"lu2017_s{i}" for i in range(6))):
        assert presets[name], name  # has a description
    for name in presets:
        sc = load_scenario(name)
        again = parse_scenario(to_toml(sc), sc.source)
        assert again == sc, name


def test_lu2016_preset_matches_table2() -> None:
    sc = load_scenario("lu2016_calm")
    by = {f.channel: f for f in sc.faults}
    assert by["imu0.acc.x"].get("bias") == 3.0
    assert by["imu0.gyro.p"].get("bias") == pytest.approx(1.5 * math.pi / 180)
    assert by["imu0.gyro.q"].get("amplitude") == pytest.approx(math.pi / 180)
    assert all(f.t_start_s == 10.0 and f.t_end_s == 30.0 for f in sc.faults)
    lu17 = load_scenario("lu2017_s5")
    assert lu17.actuator_faults[0].t_start_s == 12.0 and lu17.actuator_faults[0].surface == 1


def test_load_by_path(tmp_path: Path) -> None:
    p = tmp_path / "mine.toml"
    p.write_text(BASE)
    assert load_scenario(p).name == "mine"
    with pytest.raises(ScenarioError, match="no such file or preset"):
        load_scenario("nonexistent_preset")
