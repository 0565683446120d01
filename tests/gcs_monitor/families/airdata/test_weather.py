"""The weather estimate of the air-data family: kinematic wind by hand, the mean and the gust
RMS of known winds, the prior until converged, the hold while an instance is suspected."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_monitor.core.atmosphere import cas_from_tas
from gcs_monitor.families.airdata.weather import WeatherConfig, WeatherEstimator, wind_ned
from gcs_monitor.models.airdata import WindEnvelope

DT_US = 50_000  # 20 Hz air data


def test_kinematic_wind_by_hand() -> None:
    # heading east, 5 deg AoA = pitch (level flight), TAS 100 m/s at 1000 m, 10 m/s headwind
    alt, tas, a = 1000.0, 100.0, math.radians(5.0)
    cas = cas_from_tas(tas, alt)
    v_ground = np.array([0.0, tas - 10.0, 0.0])  # the air moves west at 10 m/s
    w = wind_ned(v_ground, np.array([0.0, a, math.pi / 2]), cas, a, 0.0, alt)
    np.testing.assert_allclose(w, [0.0, -10.0, 0.0], atol=1e-9)  # m/s: ISA round trip
    # a sideslip beta turns the air velocity towards the right wing (FRD y)
    b = math.radians(3.0)
    w = wind_ned(np.array([tas * math.cos(b), tas * math.sin(b), 0.0]),
                 np.zeros(3), cas, 0.0, b, alt)
    np.testing.assert_allclose(w, [0.0, 0.0, 0.0], atol=1e-9)


def _run(est: WeatherEstimator, winds: np.ndarray) -> WindEnvelope:
    env = est.estimate.envelope
    for k, w in enumerate(winds):
        new = est.add(k * DT_US, w)
        env = new if new is not None else env
    return env


def test_prior_until_converged_then_the_estimate() -> None:
    prior = WindEnvelope(wind_mps=18.0, turbulence_sigma_mps=0.0)
    cfg = WeatherConfig()
    est = WeatherEstimator(cfg, prior)
    # before convergence: the prior with at least start_sigma of turbulence
    assert est.estimate.envelope.turbulence_sigma_mps == cfg.start_sigma_mps
    n = round((cfg.converge_s - 1.0) * 1e6 / DT_US)
    env = _run(est, np.tile([4.0, -3.0, 0.5], (n, 1)))
    assert not est.estimate.converged and env.wind_mps == 18.0
    # a steady 5 m/s wind, no gusts: converged to it
    env = _run(est, np.tile([4.0, -3.0, 0.5], (2 * n, 1)))
    assert est.estimate.converged
    assert env.wind_mps == pytest.approx(5.0, rel=1e-9)
    assert env.wind_z_mps == pytest.approx(0.5, rel=1e-9)
    assert env.turbulence_sigma_mps == pytest.approx(0.0, abs=1e-9)


def test_gust_rms_of_white_turbulence() -> None:
    # independent N(0, sigma^2) gusts per axis at 20 Hz: the RMS about the 20 s mean over 30 s
    # windows (600 samples x 3 axes), the largest of the last 60 s: within 10 % of sigma
    sigma = 2.0
    rng = np.random.default_rng(4)
    est = WeatherEstimator(WeatherConfig(sigma_margin=1.0), WindEnvelope())
    env = _run(est, np.array([3.0, 0.0, 0.0]) + rng.normal(0.0, sigma, (3000, 3)))
    assert est.estimate.converged
    assert env.turbulence_sigma_mps == pytest.approx(sigma, rel=0.1)
    assert env.wind_mps == pytest.approx(3.0, abs=0.5)


def test_hold_freezes_the_estimate() -> None:
    est = WeatherEstimator(WeatherConfig(), WindEnvelope())
    _run(est, np.tile([2.0, 0.0, 0.0], (1000, 1)))
    assert est.estimate.envelope.wind_mps == pytest.approx(2.0)
    t0 = 1000 * DT_US
    est.hold(t0)  # an instance suspected at t0: its samples do not enter for hold_s
    for k in range(round(WeatherConfig().hold_s * 1e6 / DT_US)):
        est.add(t0 + k * DT_US, np.array([40.0, 0.0, 0.0]))  # a faulty CAS's "wind"
    assert est.estimate.envelope.wind_mps == pytest.approx(2.0)


def test_kinematic_air_by_hand() -> None:
    """Level flight east at 100 m/s ground speed, pitch 5 deg, learnt mean wind 10 m/s from the
    east and 2 m/s up: the air velocity is 110 m/s east and 2 m/s down relative to the air, so
    in body axes alpha = 5 deg + atan(2 / 110) and V_t = hypot(110, 2)."""
    est = WeatherEstimator(WeatherConfig(), WindEnvelope())
    vel = np.array([0.0, 100.0, 0.0])
    euler = np.array([0.0, math.radians(5.0), math.radians(90.0)])
    assert est.kinematic_air(vel, euler) is None  # nothing learnt yet
    est.add(0, np.array([0.0, -10.0, -2.0]))
    kin = est.kinematic_air(vel, euler)
    assert kin is not None
    assert kin[0] == pytest.approx(math.radians(5.0) + math.atan2(2.0, 110.0), abs=1e-12)
    assert kin[1] == pytest.approx(math.hypot(110.0, 2.0), abs=1e-9)


def test_samples_without_gusts_move_the_mean_and_hold_the_turbulence() -> None:
    """``gusts=False`` (a set down to its last instance, its quantity from kinematics): the mean
    wind follows, the turbulence estimate stays what the checked sensors measured."""
    rng = np.random.default_rng(8)
    est = WeatherEstimator(WeatherConfig(sigma_margin=1.0), WindEnvelope())
    env = _run(est, rng.normal(0.0, 2.0, (3000, 3)))
    sigma = env.turbulence_sigma_mps
    t0 = 3000 * DT_US
    for k in range(600):  # 30 s of a steady 8 m/s wind, no gust information
        e = est.add(t0 + k * DT_US, np.array([8.0, 0.0, 0.0]), gusts=False)
        env = e if e is not None else env
    assert env.turbulence_sigma_mps == sigma
    assert env.wind_mps == pytest.approx(8.0, abs=0.5)
