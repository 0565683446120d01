"""The GPS reference checked against itself (gcs_monitor/families/imu/gating.py, item 3)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_monitor.families.imu.gating import (
    POSITION_LSB_SIGMA_M,
    RADIUS_TOL,
    ReferenceConsistency,
)

US = 1_000_000


def _fly(ref: ReferenceConsistency, seconds: float, vel: tuple[float, float, float],
         pos_rate: tuple[float, float, float], *, frame_hz: float = 50.0, gps_every: int = 5,
         pos_noise_m: float = 0.0, seed: int = 0) -> None:
    """Frames at ``frame_hz`` with a constant velocity ``vel``; every ``gps_every``-th frame a
    GPS position moving at ``pos_rate`` (plus white noise)."""
    rng = np.random.default_rng(seed)
    n = round(seconds * frame_hz)
    for k in range(n + 1):
        t_us = round(k * US / frame_hz)
        base = None
        if k % gps_every == 0:
            t = t_us / US
            base = (t_us, [r * t + pos_noise_m * rng.standard_normal() for r in pos_rate])
        ref.add(t_us, vel, base)


def test_a_position_that_follows_its_velocity_is_consistent() -> None:
    # p = v t exactly: the trapezoid integral of a constant velocity is exact, c = 0; the
    # position's second differences are 0, so sigma_p is the GLOBAL_POSITION_INT quantisation
    # (1e-7 deg on the 6367 km sphere = 1.1112 cm, / sqrt 12 = 3.21 mm). Both c are 0, so the
    # component reported is the one with the larger margin, down: 3 sqrt(2) sigma_p / 1 s =
    # 13.6 mm/s (horizontal: 3 x 2 sigma_p + RADIUS_TOL x 20 m/s = 0.125 m/s)
    ref = ReferenceConsistency(1.0)
    _fly(ref, 3.0, (20.0, 0.0, -2.0), (20.0, 0.0, -2.0))
    assert ref.consistent() is True
    assert ref.inconsistency_mps == pytest.approx(0.0, abs=1e-9)
    assert ref.sigma_pos_m() == POSITION_LSB_SIGMA_M
    assert POSITION_LSB_SIGMA_M == pytest.approx(0.011112 / math.sqrt(12.0), rel=1e-4)
    assert ref.bound_mps == pytest.approx(3.0 * math.sqrt(2.0) * POSITION_LSB_SIGMA_M, rel=1e-6)
    # a horizontal inconsistency of 0.1 m/s is within the earth-model term at 20 m/s, 0.2 m/s
    # is not (bound 0.125 m/s)
    ref = ReferenceConsistency(1.0)
    _fly(ref, 3.0, (20.0, 0.0, 0.0), (20.1, 0.0, 0.0))
    assert ref.consistent() is True
    ref = ReferenceConsistency(1.0)
    _fly(ref, 3.0, (20.0, 0.0, 0.0), (20.2, 0.0, 0.0))
    assert ref.consistent() is False
    assert ref.inconsistency_mps == pytest.approx(0.2, rel=1e-6)
    assert ref.bound_mps == pytest.approx(6.0 * POSITION_LSB_SIGMA_M + RADIUS_TOL * 20.0,
                                          rel=1e-6)


def test_a_position_corrected_apart_from_its_velocity_is_inconsistent() -> None:
    # the position sinks 0.5 m/s faster than the velocity says (a navigation filter applying
    # corrections): c_down = 0.5 m/s exactly; the bound down is 3 sqrt(2) x 3.2 mm / 1 s
    # (no radius term down)
    ref = ReferenceConsistency(1.0)
    _fly(ref, 3.0, (20.0, 0.0, 0.0), (20.0, 0.0, 0.5))
    assert ref.consistent() is False
    assert ref.inconsistency_mps == pytest.approx(0.5, rel=1e-6)
    assert ref.bound_mps == pytest.approx(3.0 * math.sqrt(2.0) * POSITION_LSB_SIGMA_M, rel=1e-6)
    # 1 cm/s: below that bound (1.4 cm/s), consistent
    ref = ReferenceConsistency(1.0)
    _fly(ref, 3.0, (20.0, 0.0, 0.0), (20.0, 0.0, 0.01))
    assert ref.consistent() is True


def test_a_noisy_raw_gnss_position_makes_the_check_insensitive() -> None:
    # 1.5 m white position noise (the simulator's GPS): the bound down is about
    # 3 sqrt(2) 1.5 / 1 s = 6.4 m/s (sigma_p measured from the samples), so a 0.5 m/s
    # correction is not flagged: the check never blinds the family on a raw GNSS
    ref = ReferenceConsistency(1.0)
    _fly(ref, 12.0, (20.0, 0.0, 0.0), (20.0, 0.0, 0.5), pos_noise_m=1.5)
    assert ref.sigma_pos_m() == pytest.approx(1.5, rel=0.35)
    assert ref.bound_mps > 4.0
    assert ref.consistent() is True


def test_a_gap_restarts_the_integral() -> None:
    ref = ReferenceConsistency(1.0, max_gap_s=0.5)
    _fly(ref, 3.0, (20.0, 0.0, 0.0), (20.0, 0.0, 0.5))
    assert ref.consistent() is False
    # 1 s without frames: nothing is known until a full window has passed again
    ref.add(4 * US, (20.0, 0.0, 0.0), (4 * US, [80.0, 0.0, 2.0]))
    assert ref.consistent() is None
    assert math.isnan(ref.inconsistency_mps)


def test_invalid_settings_are_refused() -> None:
    with pytest.raises(ValueError):
        ReferenceConsistency(0.0)
    with pytest.raises(ValueError):
        ReferenceConsistency(1.0, 0.0)


def test_a_placeholder_position_is_not_tested() -> None:
    # a converter's constant placeholder position (ALFA) against a velocity of 20 m/s would be a
    # 20 m/s "inconsistency" and blind the accelerometer channels; a component that does not
    # change at all over the window is no measured position: nothing is tested
    ref = ReferenceConsistency(1.0)
    _fly(ref, 3.0, (20.0, 0.0, -1.0), (0.0, 0.0, 0.0))
    assert ref.consistent() is None
    # a constant horizontal placeholder with a measured altitude: only down is tested
    ref = ReferenceConsistency(1.0)
    _fly(ref, 3.0, (20.0, 0.0, -1.0), (0.0, 0.0, -1.0))
    assert ref.consistent() is True
    assert ref.inconsistency_mps == pytest.approx(0.0, abs=1e-9)
    ref = ReferenceConsistency(1.0)
    _fly(ref, 3.0, (20.0, 0.0, -1.0), (0.0, 0.0, -0.5))
    assert ref.consistent() is False
    assert ref.inconsistency_mps == pytest.approx(0.5, rel=1e-6)
