"""The integral-action tracking form of an LPV model (Chen2020 sec. IV, eqs. 23-31).

Shared by the sliding-mode controller (``sim_vehicle/autopilot/smc_lateral.py``) and its LMI
design (``gcs_monitor/filters/lpv_smc_design.py``), so that both build the same matrices.

With controlled outputs ``y_c = C_c x_p`` (eq. 23) and integral states
``x_r' = r - C_c x_p`` (eq. 25), the augmented state ``x_c = [x_r; x_p]`` obeys (eq. 27)

    x_c' = A_c x_c + B_c u_p + B_r r,   A_c = [[0, -C_c], [0, A_p]],  B_c = [0; B_p],
    B_r = [I_l; 0]

(the uncertainty enters by ``M_c = [0; M_p]``). ``B_c = B_v B_2(rho)`` (eq. 29) with
``B_v = [0; B_vp]`` fixed, and ``T_c = diag(I_l, T_n)`` (eq. 30) with ``T_n B_vp = [0; I_l]``
(eq. 31) puts the system in regular form ``x~ = T_c x_c``: the last ``l`` components of ``x~``
are the ones the virtual control ``v~ = B_2(rho) u_p`` (eq. 33) drives directly.

For the lateral model (states ``[phi, beta, p, r]``, inputs ``[aileron, rudder]``) the
controlled outputs are roll angle and sideslip (Chen2020 sec. VI) and the surfaces act on the
roll- and yaw-moment rows: ``B_vp = [0; I_2]``, ``T_n = I_4``, ``B_2(rho)`` = the ``p`` and ``r``
rows of ``B_p(rho)``. The small side-force term of the rudder in the sideslip row does not
factor through a fixed ``B_v``; it is left out of ``B_c`` (it acts as uncertainty, the
controller's integral action takes it; docs/papers-notes.md, Chen2020).

Pure functions of numpy arrays.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gcs_monitor.core.types import Mat

# Chen2020 sec. VI: roll angle and sideslip are tracked
C_C_LATERAL = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])
# the aileron and rudder act through the roll- and yaw-moment rows
B_VP_LATERAL = np.array([[0.0, 0.0], [0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])


def t_n(B_vp: Mat) -> Mat:
    """A nonsingular ``T_n`` with ``T_n B_vp = [0; I_l]`` (Chen2020 eq. 31).

    ``T_n = [B_perp^T; (B_vp^T B_vp)^{-1} B_vp^T]`` with ``B_perp`` an orthonormal basis of the
    orthogonal complement of ``range(B_vp)`` (the identity when ``B_vp = [0; I_l]``).
    """
    n, l_ = B_vp.shape
    if np.linalg.matrix_rank(B_vp) != l_:
        raise ValueError("B_vp must have full column rank (Chen2020 eq. 29: rank B_v = l)")
    if np.allclose(B_vp[: n - l_], 0.0) and np.allclose(B_vp[n - l_:], np.eye(l_)):
        return np.eye(n)
    u, _, _ = np.linalg.svd(B_vp)
    perp = u[:, l_:]
    return np.vstack([perp.T, np.linalg.solve(B_vp.T @ B_vp, B_vp.T)])


def t_c(B_vp: Mat, n_outputs: int) -> Mat:
    """``T_c = diag(I_l, T_n)`` (Chen2020 eq. 30)."""
    n = B_vp.shape[0]
    T = np.eye(n_outputs + n)
    T[n_outputs:, n_outputs:] = t_n(B_vp)
    return T


@dataclass(frozen=True, slots=True)
class TrackingForm:
    """The regular-form matrices at one scheduling point (Chen2020 eqs. 27-33).

    A_t : (l+n, l+n) ``A~_c = T_c A_c T_c^{-1}``
    B_r : (l+n, l) ``B~_r = T_c B_r = [I_l; 0]``
    B_2 : (l, m) the varying factor of ``B_c = B_v B_2`` (least squares on the ``B_vp`` rows)
    T_c : (l+n, l+n)
    """

    A_t: Mat
    B_r: Mat
    B_2: Mat
    T_c: Mat

    @property
    def n1(self) -> int:
        """Size of ``x^_1`` (Chen2020 eq. 49): the state minus the ``l`` virtual-control ones."""
        return int(self.A_t.shape[0] - self.B_2.shape[0])


def tracking_form(A_p: Mat, B_p: Mat, C_c: Mat = C_C_LATERAL,
                  B_vp: Mat = B_VP_LATERAL) -> TrackingForm:
    """The augmented system (Chen2020 eq. 27) of ``(A_p, B_p)`` in regular form (eqs. 30-33)."""
    n = A_p.shape[0]
    l_ = C_c.shape[0]
    A_c = np.zeros((l_ + n, l_ + n))
    A_c[:l_, l_:] = -C_c
    A_c[l_:, l_:] = A_p
    T = t_c(B_vp, l_)
    Tn = T[l_:, l_:]
    A_t = T @ A_c @ np.linalg.inv(T)
    B_r = np.zeros((l_ + n, l_))
    B_r[:l_] = np.eye(l_)
    # B_2 from the T_n-transformed input rows: T_n B_p = [*; B_2] when B_p = B_vp B_2
    B_2 = (Tn @ B_p)[n - l_:]
    return TrackingForm(A_t, B_r, B_2, T)


def uncertainty_input(M_p: Mat, T: Mat, n_outputs: int) -> Mat:
    """``M~_c = T_c [0; M_p]`` (Chen2020 eq. 32)."""
    M = np.zeros((T.shape[0], M_p.shape[1]))
    M[n_outputs:] = M_p
    return T @ M
