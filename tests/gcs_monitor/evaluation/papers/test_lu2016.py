"""Lu2016 experiments (gcs_monitor.evaluation.papers.lu2016)."""

from __future__ import annotations

from pathlib import Path

import pytest

from gcs_monitor.evaluation.papers import lu2016


@pytest.mark.slow
def test_lu2016_table2_gs_beats_as_in_shear_and_turbulence(tmp_path: Path) -> None:
    md = lu2016.lu2016_table2(tmp_path, 1, True)
    assert (tmp_path / "lu2016_table2.csv").is_file()
    ratios = {}
    for line in (tmp_path / "lu2016_table2_ratio.csv").read_text().splitlines()[1:]:
        scen, filt, acc, gyro = line.split(",")
        ratios[(scen, filt)] = (float(acc), float(gyro))
    for scen in ("lu2016_shear", "lu2016_turbulence"):
        acc, gyro = ratios[(scen, "atsekf")]
        assert acc > 2.0 and 0.8 < gyro < 1.25, (scen, acc, gyro)
    assert "gs_atsekf" in md
