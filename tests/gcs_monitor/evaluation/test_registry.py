"""The experiment registry and ``gcs-monitor evaluate --list / --experiment / --data-dir``."""

from __future__ import annotations

from pathlib import Path

import pytest

from gcs_monitor.cli import main
from gcs_monitor.evaluation import registry
from gcs_monitor.evaluation.data import DATA_DIR_ENV, RealDataMissing

# every name `gcs-monitor evaluate --experiment` knew before the evaluation package was split
NAMES = {
    "sim_physics", "lu2016_table2", "atmaca2025", "imu_detection", "imu_detection_hosm",
    "closed_loop", "imu_real", "triplex_fdi", "wan2018_fig45", "wan2018_fig3",
    "wan2018_onspeed", "wan2018_calibration", "wan2018_campaign", "wan2018_campaign_restart",
    "wan2018_campaign_extensions", "wan2018_campaign_literal_nrz",
    "wan2018_campaign_restart_literal_nrz", "wan2018_campaign_extensions_literal_nrz",
    "wan2018_thin_sets", "wan2018_thin_sets_declared", "triplex_thin_sets",
    "wan2018_campaign_scheduled_literal_nrz", "wan2018_campaign_lateral_literal_nrz",
    "wan2018_campaign_lateral_only_literal_nrz",
    "chen2020_design", "chen2020_ftc", "chen2020_open_loop", "chen2020_false_alarms",
    "chen2020_roll_rate", "chen2020_identify", "chen2020_tuning", "chen2020_uav",
    # issue 15: never blind, never fooled
    "rate_sweep", "presets_weather", "triplex_weather", "wan2018_campaign_weather",
    "real_flights", "gps_rate_accuracy",
    "lu2017", "lu2017_calibration", "lu2017_campaign",  # added with the actuator family
    "actuators_sim", "actuators_alfa", "triplex_actuators",
    # the campaign's false alarms examined: the defaults' raises, the yaw-rate altitude bands
    "wan2018_campaign_defaults", "chen2020_altitudes",
    "chen2020_smc",  # issue 18: Chen2020's sliding-mode controller
}


def test_every_experiment_is_registered_once() -> None:
    assert set(registry.experiments()) == NAMES


def test_evaluate_list_describes_every_experiment(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["evaluate", "--list"]) == 0
    lines = capsys.readouterr().out.splitlines()
    names = sorted(registry.experiments())
    assert [ln.split()[0] for ln in lines] == names
    assert all(len(ln.split(maxsplit=1)) == 2 for ln in lines)  # each has a description
    assert main(["evaluate", "--experiment", "no_such_experiment"]) == 2
    assert "unknown experiment 'no_such_experiment'" in capsys.readouterr().err


def test_real_data_experiment_reads_the_data_dir_option(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
        ) -> None:
    """``--data-dir`` reaches the experiment and wins over GCS_DATA_DIR; a folder without the
    data stops the experiment with a message naming the variable."""
    monkeypatch.setenv(DATA_DIR_ENV, str(tmp_path / "from_env"))
    empty = tmp_path / "empty"
    assert main(["evaluate", "--experiment", "wan2018_onspeed", "--quick", "--jobs", "1",
                 "--out", str(tmp_path / "out"), "--data-dir", str(empty)]) == 2
    err = capsys.readouterr().err
    assert f"real data not found: set {DATA_DIR_ENV}" in err and str(empty) in err
    with pytest.raises(RealDataMissing, match="from_env"):
        registry.experiments()["imu_real"](tmp_path / "out", 1, True)


def test_registry_summary_is_one_line() -> None:
    def exp(out: object, jobs: int, quick: bool) -> str:
        """Uses :func:`thing` and ``code``, over
        two lines.

        Second paragraph, not shown."""
        return ""

    assert registry.summary(exp) == "Uses thing and `code`, over two lines."  # type: ignore[arg-type]
    short = registry.summary(exp, width=20)  # type: ignore[arg-type]
    assert short.endswith(" ...") and len(short) <= 24
