"""The LPV lateral model (Chen2020 eq. 59): fit against the simulator's linearisation and
identification from a flight."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_monitor.models.lateral import (
    LateralLpv,
    LateralSamples,
    fit_lpv,
    identify_lateral_model,
)
from sim_vehicle.dynamics.linearise import lateral_lpv, lateral_lti


@pytest.mark.parametrize(("airframe", "speeds", "alt_m"),
                         [("transport", (85.0, 185.0), 1500.0), ("uav", (18.0, 35.0), 1000.0)])
def test_lpv_fit_reproduces_linearisations_between_the_fit_points(
        airframe: str, speeds: tuple[float, float], alt_m: float) -> None:
    model, err, _ = lateral_lpv(airframe, tuple(np.linspace(*speeds, 6).tolist()), alt_m)
    # p and r rows are exactly affine in V_eas, V_eas^2 at one altitude (qbar and qbar / V);
    # the phi and beta rows carry tan(theta), g / V and sin(alpha): the fit error is there
    assert err.rel_A < 0.02
    assert err.rel_B < 1e-6
    for v in (0.5 * (speeds[0] + speeds[1]), speeds[0] + 0.13 * (speeds[1] - speeds[0])):
        lti = lateral_lti(airframe, v, alt_m)  # a speed between the fit points
        A, B, c = model.matrices(lti.eas_mps)
        np.testing.assert_allclose(A[2:], lti.A[2:], rtol=1e-6, atol=1e-9)  # moment rows
        np.testing.assert_allclose(B, lti.B, rtol=1e-6, atol=1e-9)
        assert np.linalg.norm(A - lti.A) / np.linalg.norm(lti.A) < 0.02
        np.testing.assert_array_equal(c, 0.0)


def test_linearisation_has_the_textbook_structure() -> None:
    lti = lateral_lti("transport", 130.0, 1500.0)
    A = lti.A
    assert A[0, 2] == pytest.approx(1.0, abs=1e-6)  # phi' = p + tan(theta) r (level trim)
    assert A[0, 3] == pytest.approx(np.tan(lti.trim.alpha_rad), rel=1e-4)
    assert A[1, 3] == pytest.approx(-np.cos(lti.trim.alpha_rad), rel=1e-3)  # beta' ~ -r
    assert A[2, 1] < 0.0 and A[3, 1] > 0.0  # dihedral, weathercock stability
    assert A[2, 2] < 0.0 and A[3, 3] < 0.0  # roll and yaw damping


def test_fit_is_exact_on_affine_data() -> None:
    rng = np.random.default_rng(3)
    A3 = rng.normal(size=(3, 4, 4)) * np.array([1.0, 1e-2, 1e-4])[:, None, None]
    B3 = rng.normal(size=(3, 4, 2)) * np.array([1.0, 1e-2, 1e-4])[:, None, None]
    truth = LateralLpv(A3, B3, np.zeros((3, 4)), (20.0, 40.0))
    v = np.linspace(20.0, 40.0, 5)
    mats = [truth.matrices(x) for x in v]
    model, err = fit_lpv(v, [m[0] for m in mats], [m[1] for m in mats])
    np.testing.assert_allclose(model.A, A3, rtol=1e-6, atol=1e-10)  # float64 least squares
    assert err.rel_A < 1e-9 and err.eig_max_rad_s < 1e-8


def test_identification_recovers_a_known_model() -> None:
    """Equation-error least squares on a simulated excited flight of a known LPV model."""
    model, _, _ = lateral_lpv("uav", (18.0, 26.0, 35.0), 1000.0)
    rng = np.random.default_rng(7)
    dt = 0.01
    n = 60_000
    t = np.arange(n) * dt
    eas = 26.0 + 7.0 * np.sin(2 * np.pi * t / 300.0)
    u = np.zeros((n, 2))
    # random steps on both surfaces every 0.5-2 s, small: the linear model holds
    k = 0
    while k < n:
        m = int(rng.integers(25, 100))
        u[k:k + m] = rng.normal(0.0, 0.02, size=2)
        k += m
    for i in range(1, n):  # smooth steps (0.3 s lag): the derivative filter sees no corner
        u[i] = u[i - 1] + (dt / 0.3) * (u[i] - u[i - 1])
    x = np.zeros((n, 4))
    for i in range(n - 1):
        A, B, c = model.matrices(eas[i])
        # a light roll-attitude and yaw-damper loop keeps the spiral mode bounded
        ui = u[i] - np.array([0.5 * x[i, 0] + 0.05 * x[i, 2], -0.3 * x[i, 3]])
        u[i] = ui  # what the surfaces did
        x[i + 1] = x[i] + dt * (A @ x[i] + B @ ui + c)
    samples = LateralSamples(t, x, u, eas)
    ident, err = identify_lateral_model(samples, period_s=dt, smooth_s=0.15)
    # the data are explicit-Euler steps (dt |lambda_roll| ~ 0.3): the derivative filter sees
    # the continuous model to within a few per cent
    assert np.all(err.nrmse < 0.1)
    for v in (20.0, 26.0, 33.0):
        A0, B0, _ = model.matrices(v)
        A1, B1, _ = ident.matrices(v)
        assert np.linalg.norm(A1[2:] - A0[2:]) / np.linalg.norm(A0[2:]) < 0.05
        assert np.linalg.norm(B1[2:] - B0[2:]) / np.linalg.norm(B0[2:]) < 0.05


def test_samples_of_several_flights_are_kept_apart() -> None:
    from gcs_monitor.models.lateral import lateral_samples
    from gcs_monitor.telemetry.frame import Frame, ImuSample

    def flight(phase: float) -> list[Frame]:
        out = []
        for k in range(200):
            t = k * 10_000
            x = math.sin(0.5 * k * 0.01 + phase)
            out.append(Frame(t_us=t, imu=[ImuSample(t, 0, np.zeros(3), np.array([x, 0, x]))],
                             euler_rad=np.array([x, 0.0, 0.0]), att_age_s=0.0, ssa_rad=x,
                             cas_mps=np.full(3, 30.0), cas_age_s=np.zeros(3), baro_alt_m=0.0,
                             surf_pos_rad=np.array([x, 0.0, x])))
        return out

    s = lateral_samples(flight(0.0) + flight(1.0), period_s=0.01)
    assert np.all(np.diff(s.t_s) > 0.0)
    assert s.t_s.size >= 396  # both flights, nothing across the join
    # every sample is one of the flights' values (no interpolation across the join)
    assert np.allclose(s.x[:, 0], s.x[:, 3]) and np.all(np.abs(s.x[:, 0]) <= 1.0)
