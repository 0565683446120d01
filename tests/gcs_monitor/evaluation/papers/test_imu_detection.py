"""IMU detection experiments (gcs_monitor.evaluation.papers.imu_detection)."""

from __future__ import annotations

from pathlib import Path

import pytest

from gcs_monitor.evaluation.papers import imu_detection


@pytest.mark.slow
def test_imu_detection_quick_no_false_alarms(tmp_path: Path) -> None:
    imu_detection.imu_detection(tmp_path, 1, True)
    rows = (tmp_path / "imu_detection_fault_free.csv").read_text().splitlines()[1:]
    assert rows and all(int(r.split(",")[2]) == 0 for r in rows)
