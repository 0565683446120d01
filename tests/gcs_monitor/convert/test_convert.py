"""Real-data converter: frames, units, glitches (shared/data/real/README.md) and the tlog path."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from gcs_monitor.convert.formats import (
    ConvertError,
    detect_format,
    read_alfa,
    read_onspeed,
    read_zipline,
)
from gcs_monitor.convert.writer import convert_file, lu2016_table2_injector
from gcs_monitor.core.frames import dcm_ned_frd
from tests.helpers.stock_mavutil import stock_mavutil


@pytest.fixture(scope="module")
def zipline(real_data_file) -> Path:
    """The first Zipline flight of the real data (tests/conftest.py)."""
    return sorted(real_data_file("zipline_launch").glob("flight_*.csv"))[0]


def _specific_force_residual(f, mask):  # d(v)/dt - (C f + g), NED, m/s^2
    dt = np.diff(f.t_s)
    res = []
    for k in np.nonzero(mask[:-1])[0]:
        C = dcm_ned_frd(*f.euler_rad[k])
        a = C @ f.acc_frd_mps2[0][k] + np.array([0.0, 0.0, 9.78])
        res.append((f.gps_vel_ned_mps[k + 1] - f.gps_vel_ned_mps[k]) / dt[k] - a)
    return np.array(res)


def test_zipline_frames_consistent(zipline):
    """Zipline README: R_nb f + g matches dv/dt (residual RMS ~0.1-0.3 m/s^2 after launch)."""
    f = read_zipline(zipline)
    t_since_launch = f.t_s + (-5.0)
    mask = (t_since_launch > 0.5) & (t_since_launch < 7.0)
    # GPS arrays equal IMU arrays outside the reset mask, so index alignment holds here.
    assert len(f.gps_t_s) < len(f.t_s)  # the 7.4-8.9 s reset is masked
    r = _specific_force_residual(f, mask)
    rms = np.sqrt(np.mean(r**2, axis=0))
    assert np.all(rms < 1.0), rms  # m/s^2: wrong sign/frame gives ~10-20 m/s^2


def test_onspeed_units_and_roll_sign(real_data_file):
    f = read_onspeed(real_data_file("onspeed_vac_decel_stall_50hz.csv"))
    # Level flight: specific force z about -g in both IMUs (FRD, z down).
    assert abs(np.median(f.acc_frd_mps2[0][:200, 2]) + 9.8) < 0.6
    assert abs(np.median(f.acc_frd_mps2[1][:200, 2]) + 9.8) < 0.6
    # After flipping RollRate the two IMUs' roll rates agree (README: raw corr -0.97).
    c = np.corrcoef(f.omega_frd_radps[0][:, 0], f.omega_frd_radps[1][:, 0])[0, 1]
    assert c > 0.8
    # IAS 75 -> 46 kt in SI
    assert 20.0 < np.nanmin(f.cas_mps) < 26.0 and 36.0 < np.nanmax(f.cas_mps) < 40.0
    assert len(f.gps_t_s) < 200  # 5 Hz GNSS, held samples dropped


def test_alfa_flu_enu_to_frd_ned(real_data_file):
    f = read_alfa(real_data_file("carbonZ_2018-10-05-14-34-20_1_no_failure.csv"))
    # level-ish flight: FRD specific force z about -g
    assert -14.0 < np.median(f.acc_frd_mps2[0][:, 2]) < -8.0  # waypoint circuits: load factor ~1.2
    # heading from the ENU->NED conversion agrees with the velocity's course when fast
    spd = np.hypot(f.gps_vel_ned_mps[:, 0], f.gps_vel_ned_mps[:, 1])
    fast = spd > 12.0
    course = np.arctan2(f.gps_vel_ned_mps[fast, 1], f.gps_vel_ned_mps[fast, 0])
    dpsi = np.angle(np.exp(1j * (course - f.euler_rad[fast, 2])))
    assert np.median(np.abs(dpsi)) < math.radians(30.0)


def test_tlog_reads_back_with_injected_faults(tmp_path, zipline):
    out = tmp_path / "z.tlog"
    r = convert_file(zipline, out, inject_imu=lu2016_table2_injector())
    assert out.exists() and not (tmp_path / "z.tlog.tmp").exists()
    f = read_zipline(zipline)
    k = 0
    with stock_mavutil() as mavutil:
        log = mavutil.mavlink_connection(str(out))
        while (m := log.recv_match(type="HIGHRES_IMU")) is not None:
            assert m.xacc == pytest.approx(f.acc_frd_mps2[0][k, 0] + r.injected_imu[k, 0],
                                           abs=1e-4)
            k += 1
    assert k == len(f.t_s)
    assert np.max(r.injected_imu[:, 0]) == 3.0  # Lu2016 Table 2: f_Ax bias 3 m/s^2


def test_bad_input(tmp_path):
    bad = tmp_path / "x.csv"
    bad.write_text("a,b\n1,2\n")
    with pytest.raises(ConvertError, match="unknown format"):
        detect_format(bad)
    with pytest.raises(ConvertError, match="no such file"):
        convert_file(tmp_path / "missing.csv", tmp_path / "o.tlog")
