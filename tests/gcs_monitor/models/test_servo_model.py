"""The monitor's closed-loop servo model (Lu2017 eqs. 4-13, models/_servo_jit.py): Jacobians
against finite differences, the kernel against its plain-float reference, the discretisation
against the integrated model, and the NDI loop's closed-loop behaviour."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_monitor.core.kernels import load_kernels
from gcs_monitor.models.servo import (
    ServoLoopParams,
    ServoParams,
    closed_loop_derivative,
    closed_loop_jacobian,
    command_timing_noise,
    ndi_control,
    pack_params,
    propagate,
)
from tests.reference import servo_model as ref

STROKE_M = 0.35
P, LP = ServoParams(), ServoLoopParams()
PRM = pack_params(P, LP, STROKE_M)
C = ref.Consts(P, LP, STROKE_M)
KERN = load_kernels("gcs_monitor.models._servo_jit")


def _random_states(seed: int, n: int) -> list[tuple[np.ndarray, float, float]]:
    """States inside the servo's operating range (|u_NDI| < 1 kept when possible)."""
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        s = np.array([rng.uniform(-0.2, 0.2), rng.uniform(-0.2, 0.2), rng.uniform(-0.3, 0.3),
                      rng.uniform(-0.2, 0.2), rng.uniform(-0.3, 0.3), rng.uniform(-3.0, 3.0)])
        q = float(s[3] + rng.uniform(-0.01, 0.01))
        f = float(rng.uniform(-0.2, 0.2))
        s[0] = s[3] + rng.uniform(-2e-3, 2e-3)  # near the reference: the NDI law unsaturated
        g = np.empty(3)
        u = KERN.ndi(s, q, PRM, g)
        if abs(u) < 0.9 and abs(u + f) > 1e-3:  # away from the kinks (saturation, sign u)
            out.append((s, q, f))
    return out


@pytest.mark.parametrize("case", range(8))
def test_jacobian_matches_central_differences(case: int) -> None:
    s, q, f = _random_states(7, 8)[case]
    A, G = closed_loop_jacobian(s, q, f, PRM)
    steps = (1e-7, 1e-6, 1e-7, 1e-7, 1e-6, 1e-5)  # ~1e-6 of each state's range
    for j, h in enumerate(steps):
        sp, sm = s.copy(), s.copy()
        sp[j] += h
        sm[j] -= h
        col = (closed_loop_derivative(sp, q, f, PRM) - closed_loop_derivative(sm, q, f, PRM))
        # rtol 1e-6: central differences of a smooth function at h ~ 1e-7 of the state scale
        np.testing.assert_allclose(A[:, j], col / (2 * h), rtol=1e-6, atol=1e-6)
    dg = (closed_loop_derivative(s, q, f + 1e-7, PRM)
          - closed_loop_derivative(s, q, f - 1e-7, PRM)) / 2e-7
    np.testing.assert_allclose(G, dg, rtol=1e-6, atol=1e-6)


def test_jacobian_of_the_saturated_loop_is_the_open_plant() -> None:
    """With the valve saturated the NDI law depends neither on x nor on the reference states: A
    is the plant's Jacobian at constant u (Lu2017 eq. 4) beside the reference model's."""
    s = np.array([0.0, 0.0, 0.0, 0.05, 0.0, 0.0])  # 5 cm step: u_NDI saturates at +1
    A, G = closed_loop_jacobian(s, 0.05, 0.0, PRM)
    c = C.cnum / C.vm2
    expected = np.zeros((6, 6))
    expected[:3, :3] = [[0.0, 1.0, 0.0],
                        [0.0, -C.bb * C.inv_m, C.aps * C.inv_m],
                        [0.0, -c, c * (C.vmax * (-1.0 / 2.0) * 1.0 - C.leak)]]
    expected[3:, 3:] = [[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [-C.w3, -C.z2w2, -C.z2w]]
    np.testing.assert_allclose(A, expected, rtol=1e-14)
    np.testing.assert_allclose(G, [0.0, 0.0, c * C.vmax, 0.0, 0.0, 0.0], rtol=1e-14)


def test_kernel_equals_reference() -> None:
    """The kernel and the plain-float reference evaluate the same expressions in the same order:
    derivative, Jacobian and integrated state agree bit for bit; Phi, Gamma and Q_d (the
    kernel's scaling and squaring against scipy's expm) to 1e-11 relative."""
    for s, q, f in _random_states(3, 6):
        np.testing.assert_array_equal(closed_loop_derivative(s, q, f, PRM),
                                      ref.deriv(C, list(s), q, f))
        A, G = closed_loop_jacobian(s, q, f, PRM)
        Ar, Gr = ref.jacobian(C, list(s), q, f)
        np.testing.assert_array_equal(A, Ar)
        np.testing.assert_array_equal(G, Gr)
        qs = (1e-10, 1e-8, 1e-8, 0.0, 0.0, 0.0)
        pr = propagate(s, q, q + 0.003, f, 0.02, 4, PRM, q_valve=1e-4, q_state=qs)
        sr, Phr, Gmr, Qr = ref.propagate(C, list(s), q, q + 0.003, f, 0.02, 4, 1e-4, qs)
        np.testing.assert_array_equal(pr.s, sr)
        np.testing.assert_allclose(pr.Phi, Phr, rtol=1e-11, atol=1e-11 * np.abs(Phr).max())
        np.testing.assert_allclose(pr.Gamma, Gmr, rtol=1e-11, atol=1e-11 * np.abs(Gmr).max())
        np.testing.assert_allclose(pr.Qd, Qr, rtol=1e-11, atol=1e-11 * np.abs(Qr).max())
        Qt = command_timing_noise(s, q, q + 0.003, f, 0.02, 4, PRM)
        np.testing.assert_allclose(Qt, ref.command_timing_noise(C, list(s), q, q + 0.003, f,
                                                                0.02, 4), rtol=1e-12, atol=0)


def _sensitivity_errors(n_sub: int) -> tuple[float, float]:
    """Largest relative differences of Phi and Gamma from central differences of the
    RK4-integrated closed loop over one 20 ms sample."""
    s, q, f = _random_states(11, 1)[0]
    dt = 0.02
    pr = propagate(s, q, q, f, dt, n_sub, PRM)
    h = (1e-7, 1e-6, 1e-7, 1e-7, 1e-6, 1e-5)
    fd = np.empty((6, 6))
    for j in range(6):
        sp, sm = s.copy(), s.copy()
        sp[j] += h[j]
        sm[j] -= h[j]
        fd[:, j] = (propagate(sp, q, q, f, dt, n_sub, PRM).s
                    - propagate(sm, q, q, f, dt, n_sub, PRM).s) / (2 * h[j])
    dg = (propagate(s, q, q, f + 1e-6, dt, n_sub, PRM).s
          - propagate(s, q, q, f - 1e-6, dt, n_sub, PRM).s) / 2e-6
    return (float(np.abs(pr.Phi - fd).max() / np.abs(fd).max()),
            float(np.abs(pr.Gamma - dg).max() / np.abs(dg).max()))


def test_phi_and_gamma_are_the_sensitivities_of_the_integrated_loop() -> None:
    """Phi = d x_k / d x_{k-1} and Gamma = d x_k / d f^i of the RK4-integrated closed loop: the
    variational equation rides along the same RK4 stages, so they are the derivatives of the
    discrete map itself -- equal to central differences of the integration to the differences'
    own error (1e-6 relative), at any substep."""
    for n_sub in (1, 2, 8):
        assert max(_sensitivity_errors(n_sub)) < 1e-6


def test_ndi_loop_tracks_a_step_with_the_reference_model() -> None:
    """A 1 cm rod step: the closed loop follows the third-order reference model (r = 3 NDI) and
    settles on the command; the kernel's NDI law is ``models.servo.ndi_control``."""
    s = np.zeros(6)
    g = np.empty(3)
    u = KERN.ndi(s, 0.01, PRM, g)
    rddd = C.w3 * 0.01
    assert u == ndi_control(0.0, 0.0, 0.0, (0.0, 0.0, 0.0, rddd), P, LP)
    for _ in range(100):  # 2 s
        s = propagate(s, 0.01, 0.01, 0.0, 0.02, 4, PRM).s
    assert math.isclose(s[0], 0.01, rel_tol=1e-4)
    assert abs(s[0] - s[3]) < 1e-6  # on the reference


def test_constant_input_fault_offsets_the_loop_by_b_over_k0() -> None:
    """The NDI law has no integrator: a constant input fault f^i shifts the settled rod by
    ``b f / k0`` with ``b = L_g L_f^2 h`` at rest (x1'''  = nu + b f^i)."""
    s = np.zeros(6)
    f = 0.01
    for _ in range(150):
        s = propagate(s, 0.0, 0.0, f, 0.02, 4, PRM).s
    b_rest = C.aps * C.inv_m * (C.cnum / C.vm2) * C.vmax  # at x1 = x3 = 0
    # x3 settles at ~L x3 leakage balance: 1 % from the rest value of b
    assert s[0] == pytest.approx(b_rest * f / C.k0, rel=0.02)


def test_command_timing_noise_spans_the_two_extreme_profiles() -> None:
    """A 1 cm command step inside a 20 ms interval: the covariance is rank one along the
    difference of the step taken at the start and at the end, with |e|^2 / 12 on it; no step, no
    noise."""
    s = np.zeros(6)
    Q = command_timing_noise(s, 0.0, 0.01, 0.0, 0.02, 4, PRM)
    e = propagate(s, 0.01, 0.01, 0.0, 0.02, 4, PRM).s - propagate(s, 0.0, 0.0, 0.0, 0.02, 4,
                                                                   PRM).s
    np.testing.assert_allclose(Q, np.outer(e, e) / 12.0, rtol=1e-12)
    assert np.linalg.matrix_rank(Q, tol=1e-12 * np.abs(Q).max()) == 1
    assert e[3] > 0.0 and e[5] > 0.0  # the reference model moved further with the early step
    np.testing.assert_array_equal(command_timing_noise(s, 0.01, 0.01, 0.0, 0.02, 4, PRM), 0.0)
