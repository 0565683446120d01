"""The pure helpers of ``benchmarks/equality_vs.py``: no git worktree, no simulation, no replay
(the end-to-end check is the command itself)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from benchmarks.equality_vs import (
    Row,
    default_data_dir,
    format_table,
    journal_difference,
    normalise_journal,
    record_difference,
)
from gcs_monitor.evaluation.data import DATA_DIR_ENV, real_data_dir


def _journal(*alarms: tuple[float, str, float]) -> str:
    """Journal lines as AlarmJournal writes them: (magnitude, wall_time, wall_time_s)."""
    return "".join(
        json.dumps({"schema_version": 1, "type": "alarm", "channel_name": "aoa1",
                    "state": "raised", "magnitude": mag, "t_us": 20_250_000,
                    "wall_time_s": wall_s, "wall_time": wall, "estimator": "airdata_cmhe"},
                   separators=(",", ":")) + "\n"
        for mag, wall, wall_s in alarms)


def test_journals_equal_up_to_wall_time() -> None:
    base = _journal((0.05, "2026-12-01T22:05:03.805Z", 1796162703.8),
                    (0.02, "2026-12-01T22:05:03.900Z", 1796162703.9))
    new = _journal((0.05, "2026-12-02T09:00:00.000Z", 1796200000.0),
                   (0.02, "2026-12-02T09:00:00.100Z", 1796200000.1))
    assert [set(r) & {"wall_time_s", "wall_time"} for r in normalise_journal(base)] == [set()] * 2
    assert journal_difference(base, new) is None


def test_journal_difference_names_the_first_differing_alarm() -> None:
    base = _journal((0.05, "a", 1.0), (0.02, "a", 1.0))
    new = _journal((0.05, "b", 2.0), (0.03, "b", 2.0))
    assert journal_difference(base, new) == "alarm 2 (aoa1 raised): magnitude 0.02 vs 0.03"
    assert journal_difference(base, base + new) == "2 vs 4 alarms"


def test_record_difference_is_the_first_differing_line() -> None:
    report = """events identical: True (3 vs 3)
frames identical: True (1001)
imu_hosm: 1001 estimates, availability/numerics identical: True, max |diff| faults=0 residuals=0 virtual=0 states=0
imu_ts: 1001 estimates, availability/numerics identical: True, max |diff| faults=2.5e-07 residuals=0 virtual=0 states=1e-09
set statuses identical: False (2002)
health identical (availability summary aside): True
RESULT: DIFFERENT
"""  # noqa: E501 - replay_equality.py's own line lengths
    assert record_difference(report) == "imu_ts: max |diff| faults=2.5e-07 states=1e-09"
    assert record_difference("events identical: False (3 vs 4)\nRESULT: DIFFERENT") == (
        "events identical: False (3 vs 4)")


def test_table_marks_results_and_escapes_pipes() -> None:
    table = format_table([Row("lu2016_turbulence_s1", "imu2", None),
                          Row("flight_16951.lu2016", "default", "imu_ts: max |diff| faults=1")])
    assert table.splitlines() == [
        "| flight | configuration | result |",
        "|---|---|---|",
        "| lu2016_turbulence_s1 | imu2 | identical |",
        "| flight_16951.lu2016 | default | differs: imu_ts: max \\|diff\\| faults=1 |",
    ]


def test_data_dir_follows_the_evaluation_rule(monkeypatch: pytest.MonkeyPatch,
                                              tmp_path: Path) -> None:
    monkeypatch.delenv(DATA_DIR_ENV, raising=False)
    assert default_data_dir() == real_data_dir()
    monkeypatch.setenv(DATA_DIR_ENV, str(tmp_path))
    assert default_data_dir() == real_data_dir() == tmp_path
    assert default_data_dir(tmp_path / "x") == real_data_dir(tmp_path / "x")
