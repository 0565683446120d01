"""Chen2020 sec. IV sliding-mode controller: the tracking form (eqs. 27-31), the LMI design of
the switching function (Assumption 4.1), P_2 (eq. 45) and the closed-loop bound (eq. 58)."""

from __future__ import annotations

import numpy as np
import pytest

from gcs_monitor.evaluation.papers.chen2020_design import (
    EQ60,
    SmcParams,
    make_smc,
    smc_bounds,
    vertex_matrices,
)
from gcs_monitor.families.yaw_rate.design import load_design, uncertainty_matrix
from gcs_monitor.filters.lpv_smc_design import (
    lyapunov_p2,
    reduced_matrix,
    sliding_blocks,
    split,
)
from gcs_monitor.filters.lpv_smo import partition
from gcs_monitor.models.lateral_tracking import (
    B_VP_LATERAL,
    C_C_LATERAL,
    t_n,
    tracking_form,
)

DESIGN = load_design("transport")
PARAMS = SmcParams()


@pytest.fixture(scope="module")
def smc() -> tuple[object, dict[str, object]]:
    return make_smc(DESIGN, PARAMS)


def _forms() -> list:
    return [tracking_form(A, B) for A, B in vertex_matrices(DESIGN.model)]


def test_t_n_puts_any_input_directions_in_regular_form() -> None:
    """eq. 31: T_n B_vp = [0; I_l], T_n nonsingular (identity for the lateral B_vp)."""
    np.testing.assert_array_equal(t_n(B_VP_LATERAL), np.eye(4))
    rng = np.random.default_rng(7)
    B = rng.normal(size=(5, 2))
    T = t_n(B)
    np.testing.assert_allclose(T @ B, np.vstack([np.zeros((3, 2)), np.eye(2)]), atol=1e-12)
    assert abs(np.linalg.det(T)) > 1e-6


def test_augmented_system_structure() -> None:
    """eqs. 27-31 at every vertex: integrator rows x_r' = -C_c x_p (+ r through B~_r = [I; 0]),
    T_c B_v = [0; I_l], and B_c = B_v B_2 up to the rudder's side force (beta row, left out)."""
    for (A, B), f in zip(vertex_matrices(DESIGN.model), _forms(), strict=True):
        np.testing.assert_array_equal(f.A_t[:2, :2], 0.0)
        np.testing.assert_array_equal(f.A_t[:2, 2:], -C_C_LATERAL)
        np.testing.assert_allclose(f.A_t[2:, 2:], A)
        np.testing.assert_array_equal(f.B_r, np.vstack([np.eye(2), np.zeros((4, 2))]))
        B_v = np.vstack([np.zeros((2, 2)), B_VP_LATERAL])
        np.testing.assert_allclose(f.T_c @ B_v, np.vstack([np.zeros((4, 2)), np.eye(2)]))
        np.testing.assert_allclose((B_VP_LATERAL @ f.B_2)[2:], B[2:])  # p, r rows exact
        assert np.linalg.norm(B[1]) < 0.15 * np.linalg.norm(B[2:])  # what is left out


def test_switching_function_and_phi_p2(smc: tuple) -> None:
    """eq. 39: S B~_v = I_l; eq. 42: Phi Hurwitz; eq. 45: P_2 Phi + Phi^T P_2 = -I, P_2 > 0."""
    gains, _ = smc
    B_vt = np.vstack([np.zeros((4, 2)), np.eye(2)])
    np.testing.assert_array_equal(gains.S @ B_vt, np.eye(2))
    assert np.max(np.linalg.eigvals(gains.Phi).real) < 0.0
    np.testing.assert_allclose(gains.P2 @ gains.Phi + gains.Phi.T @ gains.P2, -np.eye(2),
                               atol=1e-12)
    assert np.min(np.linalg.eigvalsh(gains.P2)) > 0.0
    # a non-diagonal Hurwitz Phi: the same identity
    Phi = np.array([[-2.0, 1.0], [0.0, -3.0]])
    P2 = lyapunov_p2(Phi)
    np.testing.assert_allclose(P2 @ Phi + Phi.T @ P2, -np.eye(2), atol=1e-12)
    with pytest.raises(ValueError, match="Hurwitz"):
        lyapunov_p2(np.array([[0.1, 0.0], [0.0, -1.0]]))


def test_n_stabilises_the_sliding_motion_at_every_vertex(smc: tuple) -> None:
    """Assumption 4.1: A~_c11 - A~_c12 N stable at every vertex with the requested decay and
    modulus, and the common P~_1 of the LMI (checked through the eigenvalues of a convex
    combination, which a common Lyapunov matrix makes stable too)."""
    gains, info = smc
    forms = _forms()
    for f in forms:
        eig = np.linalg.eigvals(reduced_matrix(f, gains.N))
        assert np.max(eig.real) <= -PARAMS.decay_radps * (1 - 1e-6)
        assert np.max(np.abs(eig)) <= PARAMS.radius_radps * (1 + 1e-6)
    mid = reduced_matrix(forms[0], gains.N) * 0.3 + reduced_matrix(forms[3], gains.N) * 0.7
    assert np.max(np.linalg.eigvals(mid).real) < -PARAMS.decay_radps * (1 - 1e-6)
    assert info["max_real"] <= -PARAMS.decay_radps * (1 - 1e-6)


def test_sliding_blocks_follow_from_the_regular_form(smc: tuple) -> None:
    """eqs. 51-57 for the yaw-rate sensor: e_f enters x^_1 through the column of r in
    A~_c12 (the x^_1 rows of A~_c H~_p; H~_c = 0 as C_c H_p = 0) and x_p directly in r."""
    gains, _ = smc
    M = uncertainty_matrix(EQ60)
    for f, b in zip(_forms(), sliding_blocks(_forms(), gains.N, (3,), M, C_C_LATERAL),
                    strict=True):
        _, A12 = split(f)
        np.testing.assert_allclose(b.H_c[:, 0], A12[:, 1])
        np.testing.assert_array_equal(b.M_c, 0.0)  # eq. 60's xi is matched: sliding rejects it
        np.testing.assert_array_equal(b.D_f, np.array([[0.0], [0.0], [0.0], [1.0]]))
        np.testing.assert_allclose(b.C_c[:2], np.hstack([np.zeros((2, 2)), np.eye(2)]))
        np.testing.assert_allclose(b.C_c[2:], -gains.N)


def _hinf(A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray) -> float:
    """Peak gain over a frequency grid (a lower bound of the H-infinity norm)."""
    n = A.shape[0]
    return max(float(np.linalg.svd(C @ np.linalg.solve(1j * w * np.eye(n) - A, B) + D,
                                   compute_uv=False)[0])
               for w in np.concatenate([[0.0], np.logspace(-3, 2, 400)]))


def test_closed_loop_bound_is_an_upper_bound_at_every_vertex(smc: tuple) -> None:
    """eq. 58: the LMI bound (common P over the vertices) is at least the frozen-vertex LTI
    gain xi -> x_p of A_s = [[A^s_11, H^_1], [0, A~_11]], M_s = [0; -M~_1], C_s = [C, -D_f],
    built here by hand; designing L_1 jointly does not do worse than the shipped L_1."""
    gains, _ = smc
    rows = smc_bounds(DESIGN, gains, l1_max=(1.0,))
    shipped, joint = rows[0][1], rows[1][1]
    assert rows[0][3] == rows[1][3] == "optimal"
    assert joint <= shipped * (1 + 1e-6)
    sd = DESIGN.sensors["r"]
    M = uncertainty_matrix(EQ60)
    for (A, _), f in zip(vertex_matrices(DESIGN.model), _forms(), strict=True):
        blk = partition(A, sd.faulty, sd.A_f)
        At11 = blk["A11"] + sd.L1 @ blk["A211"]
        Mt1 = M[[3]] + sd.L1 @ M[[0, 1, 2]]
        _, A12 = split(f)
        As = np.block([[reduced_matrix(f, gains.N), -A12[:, [1]]],
                       [np.zeros((1, 4)), At11]])  # e_f = -e~_1
        Ms = np.vstack([np.zeros((4, 2)), -Mt1])
        Cs = np.hstack([np.vstack([np.hstack([np.zeros((2, 2)), np.eye(2)]), -gains.N]),
                        np.array([[0.0], [0.0], [0.0], [-1.0]])])
        assert np.max(np.linalg.eigvals(As).real) < 0.0
        assert _hinf(As, Ms, Cs, np.zeros((4, 2))) <= shipped * (1 + 1e-6)
