"""Wan2018 on the real OnSpeed flight (gcs_monitor.evaluation.papers.wan2018_real)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gcs_monitor.convert.formats import read_onspeed
from gcs_monitor.evaluation.papers import wan2018_real


def test_measured_noise_recovers_white_noise_on_a_ramp() -> None:
    rng = np.random.default_rng(0)
    x = np.linspace(0.0, 5.0, 5000) + rng.normal(0.0, 0.1, 5000)
    assert wan2018_real.measured_noise(x) == pytest.approx(0.1, rel=0.05)


def test_truncated_onspeed_flight_ends_before_the_stall(real_data_file) -> None:
    path: Path = real_data_file(wan2018_real.ONSPEED_FILE)
    full = read_onspeed(path)
    f = wan2018_real.truncate_flight(full, wan2018_real.ONSPEED_END_S)
    assert f.t_s[-1] <= wan2018_real.ONSPEED_END_S < full.t_s[-1]
    assert len(f.aoa_rad) == len(f.cas_mps) == len(f.air_t_s) <= len(full.air_t_s)
    assert len(f.acc_frd_mps2[0]) == len(f.t_s) and f.gps_t_s[-1] <= f.t_s[-1] + 1.0
