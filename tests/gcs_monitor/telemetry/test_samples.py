"""interpolate_gps on hand-made samples: weights, hold, gap and start-of-data rules; imu_chord
(the interpolation error the IMU measures) on hand-derived accelerations."""

from __future__ import annotations

import math

import numpy as np

from gcs_monitor.telemetry.samples import gps_sample, imu_chord, interpolate_gps

RING = [gps_sample(1_000_000, 10.0, 0.0, 1.0, 0.1, 0.2, 100.0),
        gps_sample(1_100_000, 12.0, -1.0, 0.0, 0.1, 0.2, 101.0),
        gps_sample(1_200_000, 13.0, -1.0, 0.0, 0.1, 0.2, 102.0)]
BIG = 10**9


def test_linear_weights_by_hand():
    q = interpolate_gps(RING, 1_025_000, BIG, BIG)  # a quarter of the way from sample 0 to 1
    np.testing.assert_allclose(q.vel_ned_mps, [10.5, -0.25, 0.75], rtol=0, atol=1e-12)
    assert q.interpolated and q.base is RING[0] and math.isclose(q.age_s, 0.025)


def test_exactly_on_a_sample():
    q = interpolate_gps(RING, 1_100_000, BIG, BIG)
    np.testing.assert_allclose(q.vel_ned_mps, [12.0, -1.0, 0.0], atol=1e-12)
    assert q.age_s == 0.0 and q.base is RING[1]


def test_past_the_newest_sample_holds_without_extrapolating():
    q = interpolate_gps(RING, 1_250_000, BIG, 100_000)
    np.testing.assert_array_equal(q.vel_ned_mps, [13.0, -1.0, 0.0])
    assert not q.interpolated and math.isclose(q.age_s, 0.05)
    q = interpolate_gps(RING, 1_400_000, BIG, 100_000)  # held longer than allowed
    assert q.vel_ned_mps is None and math.isclose(q.age_s, 0.2)


def test_outage_is_not_interpolated_across():
    q = interpolate_gps(RING, 1_050_000, 50_000, 100_000)  # samples 100 ms apart > 50 ms gap
    np.testing.assert_array_equal(q.vel_ned_mps, [10.0, 0.0, 1.0])
    assert not q.interpolated


def test_before_the_first_sample_and_empty():
    assert interpolate_gps(RING, 999_999, BIG, BIG).vel_ned_mps is None
    q = interpolate_gps([], 5, BIG, BIG)
    assert q.vel_ned_mps is None and q.age_s == math.inf and q.base is None


def test_bracketing_pair_is_returned():
    q = interpolate_gps(RING, 1_025_000, BIG, BIG)
    assert q.base is RING[0] and q.upper is RING[1]
    assert interpolate_gps(RING, 1_250_000, BIG, BIG).upper is None  # held


# 100 Hz IMU samples over a 1 s GPS interval [2 s, 3 s]
T_US = list(range(2_000_000, 3_000_001, 10_000))


def _acc(fn):
    t = (np.array(T_US) - 2_000_000) * 1e-6
    return np.stack([fn(t), np.zeros_like(t), -fn(t)], axis=1)


def test_chord_error_of_a_constant_jerk_by_hand():
    # a = j tau (j = 2 m/s^3): v = j tau^2 / 2, chord slope j T / 2 = 1 m/s^2, so
    # e(tau) = tau * 1 - tau^2 = j tau (T - tau) / 2: 0.25 m/s at mid-interval, 0.1875 at 0.25 s,
    # zero at both samples (the trapezoid is exact on a linear acceleration)
    c = imu_chord(T_US, _acc(lambda t: 2.0 * t), 2_000_000, 3_000_000)
    assert c is not None
    np.testing.assert_allclose(c.mean_acc, [1.0, 0.0, -1.0], atol=1e-12)
    np.testing.assert_allclose(c.error_at(2_500_000), [0.25, 0.0, -0.25], atol=1e-12)
    np.testing.assert_allclose(c.error_at(2_250_000), [0.1875, 0.0, -0.1875], atol=1e-12)
    np.testing.assert_allclose(c.error_at(2_255_000), [0.255 - 0.255**2, 0.0,
                                                       -(0.255 - 0.255**2)], atol=1e-4)
    np.testing.assert_allclose(c.error_at(2_000_000), 0.0, atol=1e-12)
    np.testing.assert_allclose(c.error_at(3_000_000), 0.0, atol=1e-12)


def test_chord_error_of_a_constant_bias_is_zero():
    # a constant acceleration (or an accelerometer bias added to it) is the chord's own slope:
    # the GPS measures it, the chord error does not hide it
    c = imu_chord(T_US, _acc(lambda t: 0.7 + 0.0 * t), 2_000_000, 3_000_000)
    assert c is not None
    for t in (2_100_000, 2_500_000, 2_990_000):
        np.testing.assert_allclose(c.error_at(t), 0.0, atol=1e-12)


def test_chord_needs_samples_covering_the_interval():
    acc = _acc(lambda t: t)
    assert imu_chord(T_US[1:], acc[1:], 2_000_000, 3_000_000) is None  # starts late
    assert imu_chord(T_US[:-1], acc[:-1], 2_000_000, 3_000_000) is None  # ends early
    assert imu_chord(T_US, acc, 2_000_000, 4_000_000) is None


def _chord_numpy(t_us, acc, t0_us, t1_us):
    """imu_chord's values in its original numpy formulation (trapezoid, cumsum, np.interp)."""
    ts = np.asarray(t_us, dtype=np.float64) * 1e-6
    a = np.asarray(acc, dtype=np.float64)
    steps = 0.5 * (a[1:] + a[:-1]) * np.diff(ts)[:, None]
    cum = np.vstack((np.zeros((1, 3)), np.cumsum(steps, axis=0)))
    ends = np.array([np.interp((t0_us * 1e-6, t1_us * 1e-6), ts, cum[:, i]) for i in range(3)])
    mean = (ends[:, 1] - ends[:, 0]) / ((t1_us - t0_us) * 1e-6)
    return cum - ends[:, 0], mean


def test_chord_is_bit_identical_to_the_numpy_formulation():
    # the Python-float implementation keeps numpy's operation order: not one bit may differ
    rng = np.random.default_rng(3)
    for it in range(2000):
        n = int(rng.integers(2, 25))
        dts = rng.integers(1, 30_000, n)
        t = (int(rng.integers(0, 2**50)) + np.cumsum(dts)).tolist()
        acc = rng.normal(0.0, 10.0, (n, 3)) * 10.0 ** int(rng.integers(-3, 3))
        acc[int(rng.integers(0, n))] = -0.0
        t0 = t[0] if it % 3 == 0 else t[0] + int(rng.integers(0, dts[1] + 1))
        t1 = t[-1] if it % 2 == 0 else max(t0 + 1, t[-1] - int(rng.integers(0, dts[-1])))
        ch = imu_chord(t, acc, t0, t1)
        assert ch is not None
        dv, mean = _chord_numpy(t, acc, t0, t1)
        assert np.array(ch.dv).tobytes() == dv.tobytes()
        assert np.array(ch.mean_acc).tobytes() == mean.tobytes()


def test_fast_constructors_build_the_same_objects():
    from gcs_monitor.telemetry.frame import ImuSample, new_imu_sample
    from gcs_monitor.telemetry.samples import GpsQuery, _query

    a, w = np.array([1.0, 2.0, 3.0]), np.array([0.1, 0.2, 0.3])
    s = new_imu_sample(5, 1, a, w)
    assert type(s) is ImuSample and s == ImuSample(5, 1, a, w) and repr(s) == repr(
        ImuSample(5, 1, a, w))
    assert s.acc_frd_mps2 is a and s.omega_frd_radps is w
    q = _query(a, 0.5, RING[0], True, RING[1])
    assert type(q) is GpsQuery and repr(q) == repr(GpsQuery(a, 0.5, RING[0], True, RING[1]))
    assert _query(None, math.inf, None, False, None) == GpsQuery(None, math.inf, None, False)
