"""interpolate_gps on hand-made samples: weights, hold, gap and start-of-data rules."""

from __future__ import annotations

import math

import numpy as np

from gcs_monitor.telemetry.samples import gps_sample, interpolate_gps

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
