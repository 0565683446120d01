"""GNSS velocity lag and boot-clock rate measured from a log (convert/alignment.py): synthetic
flights with a known lag and clock, and the real logs they were found on."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from gcs_monitor.convert.alignment import clock_rate, clock_wrong, gnss_velocity_lag_s
from gcs_monitor.convert.formats import read_onspeed
from gcs_monitor.convert.logs import read_messages
from gcs_monitor.core.constants import GRAVITY_STD_MPS2


def _manoeuvring(seconds: float = 60.0, imu_hz: float = 50.0, seed: int = 3):
    """A body accelerating in all three axes (level attitude, random smooth accelerations)
    seen by a perfect IMU; its true NED velocity."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, seconds, 1.0 / imu_hz)
    a = np.zeros((len(t), 3))
    for k in range(3):  # sum of sines, 0.1-1 Hz, ~1 m/s^2
        for _ in range(4):
            f, ph = rng.uniform(0.1, 1.0), rng.uniform(0, 2 * math.pi)
            a[:, k] += 0.5 * np.sin(2 * math.pi * f * t + ph)
    v = np.vstack([np.zeros(3), np.cumsum(0.5 * (a[1:] + a[:-1]) / imu_hz, axis=0)])
    f_frd = a - [0.0, 0.0, GRAVITY_STD_MPS2]  # level: FRD = NED, specific force = a - g
    return t, f_frd, np.zeros((len(t), 3)), v


def test_a_known_lag_is_found() -> None:
    t, f, eul, v = _manoeuvring()
    t_gps = np.arange(1.0, 59.0, 0.2)  # 5 Hz GNSS whose velocity is 0.15 s old
    lag = 0.15
    v_gps = np.column_stack([np.interp(t_gps - lag, t, v[:, k]) for k in range(3)])
    v_gps += np.random.default_rng(1).normal(0.0, 0.03, v_gps.shape)  # receiver noise
    est = gnss_velocity_lag_s(t, f, eul, t_gps, v_gps)
    assert est.determined and abs(est.lag_s - lag) <= 0.02, est
    # an accelerometer bias is no lag: the per-increment bias term absorbs it
    est_b = gnss_velocity_lag_s(t, f + [0.3, -0.2, 0.1], eul, t_gps, v_gps)
    assert est_b.determined and abs(est_b.lag_s - lag) <= 0.02, est_b


def test_no_lag_and_no_motion_give_zero() -> None:
    t, f, eul, v = _manoeuvring()
    t_gps = np.arange(1.0, 59.0, 0.2)
    v_gps = np.column_stack([np.interp(t_gps, t, v[:, k]) for k in range(3)])
    assert gnss_velocity_lag_s(t, f, eul, t_gps, v_gps).lag_s <= 0.01
    # a vehicle that does not accelerate says nothing about the lag: not determined, kept
    still = gnss_velocity_lag_s(t, np.tile([0.0, 0.0, -GRAVITY_STD_MPS2], (len(t), 1)), eul,
                                t_gps, np.tile([20.0, 0.0, 0.0], (len(t_gps), 1)))
    assert not still.determined and still.lag_s == 0.0


def test_clock_rate() -> None:
    tg = np.arange(0.0, 100.0, 0.2)
    jitter = np.random.default_rng(2).uniform(0.0, 0.02, len(tg))
    assert abs(clock_rate(tg + jitter, tg) - 1.0) < 1e-3 and not clock_wrong(1.0 + 5e-5)
    slow = 0.917 * tg + jitter
    assert abs(clock_rate(slow, tg) - 0.917) < 1e-3 and clock_wrong(clock_rate(slow, tg))
    assert math.isnan(clock_rate(tg[:5], tg[:5]))


def _notes(path: Path) -> tuple[list[str], list[str]]:
    msgs, info = read_messages(path)
    for _ in msgs:  # the reader fills its info as it goes
        pass
    return info.notes, info.warnings


def test_erle_copter_gps_lag_and_clock(real_data_file) -> None:
    """erle_copter_16.BIN: the receiver's velocity lags the IMU by ~0.2 s; the boot clock is
    sound. erle_copter_loiter_rtl.bin: the boot clock runs 8 % slow against GPS time (Erle
    PXF), 111 GPS records repeat the previous solution, the same ~0.2 s lag."""
    notes, warnings = _notes(real_data_file("ardupilot_bin/erle_copter_16.BIN"))
    lag = float(re.search(r"lag behind the IMU measured ([0-9.]+) s", " ".join(notes)).group(1))
    assert 0.15 <= lag <= 0.25 and not warnings
    notes, warnings = _notes(real_data_file("ardupilot_bin/erle_copter_loiter_rtl.bin"))
    rate = float(re.search(r"boot clock runs at ([0-9.]+) of GPS time", " ".join(warnings))
                 .group(1))
    assert 0.90 <= rate <= 0.94
    assert any(n.startswith("GPS: 111 records repeat the previous solution") for n in notes)
    lag = float(re.search(r"lag behind the IMU measured ([0-9.]+) s", " ".join(notes)).group(1))
    assert 0.15 <= lag <= 0.3


def test_onspeed_gnss_velocity_lag(real_data_file) -> None:
    """The VN-300's raw GNSS velocity lags its IMU (0.1-0.2 s); the INS velocity does not."""
    f = read_onspeed(real_data_file("onspeed_vac_decel_stall_50hz.csv"))
    note = next(n for n in f.notes if n.startswith("VN-300 GNSS velocity"))
    lag = float(re.search(r"measured ([0-9.]+) s", note).group(1))
    assert 0.08 <= lag <= 0.22
