"""Sensor suite: rates, noise statistics against the paper tables, determinism, GPS latency."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_monitor.core.constants import EARTH_RADIUS_M
from gcs_monitor.core.units import DEG2RAD
from sim_vehicle.sensors.channels import channel_catalogue, group_channels
from sim_vehicle.sensors.noise import ATMACA2025, LU2016, SensorSet
from sim_vehicle.sensors.suite import SensorSuite, group_sigma, true_values
from sim_vehicle.state import TrueState

DT_US = 10_000  # 100 Hz physics step


def make_state(t_s: float = 0.0, **kw: object) -> TrueState:
    base = dict(
        t_s=t_s,
        lat_rad=52.0 * DEG2RAD,
        lon_rad=4.4 * DEG2RAD,
        alt_m=1000.0,
        vel_ned_mps=np.array([100.0, 5.0, -2.0]),
        euler_rad=np.array([0.1, 0.05, 1.0]),
        omega_frd_radps=np.array([0.01, -0.02, 0.03]),
        acc_frd_mps2=np.array([0.5, -0.1, -9.7]),
        wind_ned_mps=np.zeros(3),
        tas_mps=100.0,
        aoa_rad=0.05,
        ssa_rad=0.01,
        pressure_alt_m=990.0,
        static_pressure_pa=89_000.0,
        oat_k=281.7,
        cas_mps=95.0,
        surf_cmd_rad=np.zeros(3),
        surf_pos_rad=np.zeros(3),
        rod_pos_m=np.zeros(3),
        throttle=0.5,
    )
    base.update(kw)
    return TrueState(**base)  # type: ignore[arg-type]


def run_suite(sset: SensorSet, seconds: float, **kw: object) -> dict[str, list]:
    suite = SensorSuite(sset, **kw)  # type: ignore[arg-type]
    st = make_state()
    out: dict[str, list] = {}
    for k in range(round(seconds * 1e6 / DT_US)):
        for smp in suite.step(st, k * DT_US):
            out.setdefault(smp.group, []).append((smp.t_us, smp.values))
    return out


@pytest.mark.parametrize("sset", [LU2016, ATMACA2025], ids=lambda s: s.name)
def test_noise_std_matches_table_within_10_percent(sset: SensorSet) -> None:
    out = run_suite(sset, 30.0, n_imu=3, seed=4)
    st = make_state()
    for group, samples in out.items():
        vals = np.array([v for _, v in samples])
        err = vals - true_values(group, st)
        expected = group_sigma(group, sset.noise, st.lat_rad)
        # >= 300 samples per channel: the sample std is within ~4% (3 sigma) of the true one
        assert len(vals) >= 300
        np.testing.assert_allclose(err.std(axis=0), expected, rtol=0.10, err_msg=group)
        np.testing.assert_allclose(err.mean(axis=0), 0.0, atol=float(4 * expected.max()))


def test_table_values_are_the_papers() -> None:
    # Lu2016 Table 1
    assert LU2016.noise.acc_mps2 == 0.01
    assert math.isclose(LU2016.noise.gyro_radps, 0.01 * math.pi / 180)
    assert math.isclose(LU2016.noise.aoa_rad, 0.1 * math.pi / 180)
    assert LU2016.noise.cas_mps == 0.1 and LU2016.noise.gps_vel_mps == 0.01
    # Atmaca2025 Table 1
    assert ATMACA2025.noise.euler_rad == (8.7e-5, 8.7e-5, 1.7e-4)
    assert ATMACA2025.noise.gyro_radps == 4.1e-6 and ATMACA2025.noise.acc_mps2 == 6.9e-4
    assert ATMACA2025.rates.gps_hz == 10.0 and ATMACA2025.rates.airdata_hz == 100.0
    # lat sigma in rad is position sigma over the earth radius
    sig = group_sigma("gps", LU2016.noise, 0.0)
    assert math.isclose(sig[3], LU2016.noise.gps_pos_m / EARTH_RADIUS_M)


def test_rates_and_timestamps() -> None:
    out = run_suite(LU2016, 10.0, n_imu=2)
    r = LU2016.rates
    expected = {"imu0": r.imu_hz, "imu1": r.imu_hz, "attitude": r.attitude_hz, "gps": r.gps_hz,
                "airdata": r.airdata_hz, "baro": r.baro_hz, "static": r.static_hz}
    for g, hz in expected.items():
        assert len(out[g]) == round(10.0 * hz), g
        t = np.array([t for t, _ in out[g]])
        assert np.all(np.diff(t) == round(1e6 / hz))


def test_deterministic_and_instances_independent() -> None:
    a = run_suite(LU2016, 1.0, n_imu=3, seed=7)
    b = run_suite(LU2016, 1.0, n_imu=3, seed=7)
    c = run_suite(LU2016, 1.0, n_imu=3, seed=8)
    for g in a:
        np.testing.assert_array_equal([v for _, v in a[g]], [v for _, v in b[g]])
    assert not np.array_equal(a["imu0"][0][1], c["imu0"][0][1])
    # separate generators per instance: imu0 and imu1 noise differ
    assert not np.allclose(a["imu0"][0][1], a["imu1"][0][1])


def test_gps_latency_reports_old_truth() -> None:
    suite = SensorSuite(LU2016, gps_latency_s=0.2, seed=1)
    got = {}
    for k in range(101):
        st = make_state(vel_ned_mps=np.array([float(k), 0.0, 0.0]))  # v_N = step index
        for smp in suite.step(st, k * DT_US):
            if smp.group == "gps":
                got[k] = smp.values[0]
    # 0.2 s = 20 steps of latency: sample at step k reports v_N = k - 20 (noise 0.01 m/s)
    for k, v in got.items():
        if k >= 20:
            assert abs(v - (k - 20)) < 0.06


def test_channel_catalogue() -> None:
    cat = channel_catalogue(2)
    assert "imu1.gyro.r" in cat and "imu2.acc.x" not in cat
    assert cat["aoa1"].dimension == "angle" and cat["cas2"].dimension == "speed"
    assert cat["cas2"].group == "airdata" and cat["cas2"].index == 5
    assert len(group_channels("airdata")) == 7
