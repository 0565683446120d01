"""sim-vehicle CLI: list, run with overrides, exit code 2 on bad input."""

from __future__ import annotations

from pathlib import Path

import pytest

from sim_vehicle.cli import EXIT_BAD_INPUT, main


def test_list_shows_presets(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    assert "lu2016_calm" in out and "demo_airdata_faults" in out and "Lu2016 Table 2" in out


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["run", "no_such_preset"], "no such file or preset"),
        (["run", "demo_airdata_faults", "--duration", "-1"], "--duration"),
        (["run", "demo_airdata_faults", "--live", "--udp", "host:xx"], "--udp"),
    ],
)
def test_bad_input_exits_2(
    argv: list[str], needle: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(argv) == EXIT_BAD_INPUT
    assert needle in capsys.readouterr().err


def test_bad_scenario_file_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    p = tmp_path / "bad.toml"
    p.write_text('[scenario]\nairframe = "transport"\nduration_s = 5.0\nspeed = 3\n')
    assert main(["run", str(p)]) == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert "bad.toml" in err and "'speed'" in err


def test_run_real_physics_short(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rc = main(["run", "demo_airdata_faults", "--duration", "2", "--seed", "9", "--out",
               str(tmp_path), "--no-progress"])
    assert rc == 0
    out = capsys.readouterr().out
    assert "HIGHRES_IMU 603" in out and "3 injected" in out
    assert (tmp_path / "demo_airdata_faults_s9.tlog").is_file()
    assert (tmp_path / "demo_airdata_faults_s9.truth.npz").is_file()
    assert (tmp_path / "demo_airdata_faults_s9.scenario.toml").is_file()
