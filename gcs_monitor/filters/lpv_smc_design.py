"""LMI design of Chen2020's integral-action LPV sliding-mode controller (sec. IV), with cvxpy.

The controller runs in the simulator (``sim_vehicle/autopilot/smc_lateral.py``); this module
gives it its matrices and the closed-loop L2-gain bound of eq. 58. The tracking form
(eqs. 27-33) comes from :mod:`gcs_monitor.models.lateral_tracking` (taken here through the
:class:`TrackingForm` protocol), the LMI helpers and the
bounded-real-lemma design from :mod:`gcs_monitor.filters.lpv_smo_design`.

* **Sliding surface** ``N`` (Assumption 4.1, Remark 4.1): with ``x^ = [x^_1; x^_2]`` split at
  the last ``l`` states (eq. 49), sliding on ``S x^ = N x^_1 + x^_2 = 0`` leaves
  ``x^_1' = (A~_c11 - A~_c12 N) x^_1`` (eq. 51). ``N`` is fixed over Omega (Chen2020 sec. V:
  "the design freedom N(rho) is chosen as fixed"), found with ``X = P~_1^{-1}``, ``Y = N X``:
  at every vertex ``He(A~_c11 X - A~_c12 Y) + 2 a X < 0`` (decay rate ``a``: Assumption 4.1
  with a margin) and the disk LMI ``[[-R X, A X - B Y], [., -R X]] < 0`` (eigenvalues within
  radius ``R``: the sliding motion no faster than the actuators can follow), ``X >= I``,
  minimising ``||Y||`` (the smallest gains that place the motion there). A common ``X`` at
  the vertices holds on the box Omega (the matrices are affine in rho).
* **Phi, P_2**: ``Phi`` Hurwitz (given), ``P_2`` from the Lyapunov equation (eq. 45).
* **Closed-loop bound** (eqs. 51-58): the reduced-order motion of ``x^_1`` driven by the
  observer's fault-estimation error ``e_f = -A_f^{-1} A_212 e~_1`` coupled with the observer's
  sliding dynamics (eq. 22), as :class:`~gcs_monitor.filters.lpv_smo_design.ClosedLoopBlock`
  per vertex, so that :func:`~gcs_monitor.filters.lpv_smo_design.design_l1` computes the bound
  with the shipped ``L_1`` or designs ``L_1`` jointly (N fixed: the joint problem stays an LMI).
* **Modulation gain** ``K = m eta_1 + h chi~ + eta_2`` (eq. 46) with ``m = ||S M^||`` and
  ``h = ||S H^||`` at their worst over the vertices (a norm of an affine matrix is convex in
  rho: its maximum on the box is at a vertex).
"""

from __future__ import annotations

import importlib
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import scipy.linalg

from gcs_monitor.core.types import Mat
from gcs_monitor.filters.lpv_smo import partition
from gcs_monitor.filters.lpv_smo_design import ClosedLoopBlock, he, solve


class TrackingForm(Protocol):
    """The regular form at one scheduling point (Chen2020 eqs. 27-33), as
    :class:`gcs_monitor.models.lateral_tracking.TrackingForm` gives it (filters know no model:
    the layer contract keeps them apart)."""

    @property
    def A_t(self) -> Mat: ...  # (l+n, l+n) A~_c

    @property
    def B_2(self) -> Mat: ...  # (l, m)

    @property
    def T_c(self) -> Mat: ...  # (l+n, l+n)

    @property
    def n1(self) -> int: ...  # l+n-l: the size of x^_1


def split(form: TrackingForm) -> tuple[Mat, Mat]:
    """``A~_c11`` (n1, n1) and ``A~_c12`` (n1, l) of Chen2020 eq. 49."""
    n1 = form.n1
    return form.A_t[:n1, :n1], form.A_t[:n1, n1:]


def reduced_matrix(form: TrackingForm, N: Mat) -> Mat:
    """``A^s_11 = A~_c11 - A~_c12 N`` (Chen2020 Assumption 4.1), the sliding motion's matrix."""
    A11, A12 = split(form)
    return A11 - A12 @ N


@dataclass(frozen=True, slots=True)
class SurfaceResult:
    N: Mat  # (l, n1)
    P1: Mat  # (n1, n1) P~_1 of Assumption 4.1 (= X^{-1})
    max_real: float  # worst largest real part of the sliding motion's eigenvalues, vertices
    max_abs: float  # worst largest modulus, vertices (1/s)
    status: str
    solver: str


def design_surface(forms: Sequence[TrackingForm], *, decay: float, radius: float,
                   solver: str = "CLARABEL") -> SurfaceResult:
    """The fixed ``N`` of the switching function (see the module docstring)."""
    cp: Any = importlib.import_module("cvxpy")
    n1 = forms[0].n1
    l_ = forms[0].B_2.shape[0]
    X = cp.Variable((n1, n1), symmetric=True)
    Y = cp.Variable((l_, n1))
    eps = 1e-7
    cons = [X >> np.eye(n1)]
    for f in forms:
        A11, A12 = split(f)
        AX = A11 @ X - A12 @ Y
        cons.append(he(AX) + 2.0 * decay * X << -eps * np.eye(n1))
        disk = cp.bmat([[-radius * X, AX], [AX.T, -radius * X]])
        cons.append(0.5 * (disk + disk.T) << -eps * np.eye(2 * n1))
    prob = cp.Problem(cp.Minimize(cp.norm(Y, "fro")), cons)
    solver = solve(prob, solver)
    if X.value is None or Y.value is None:
        nan = np.full((l_, n1), math.nan)
        return SurfaceResult(nan, np.full((n1, n1), math.nan), math.nan, math.nan,
                             str(prob.status), solver)
    Xv = np.asarray(X.value)
    N = np.asarray(Y.value) @ np.linalg.inv(Xv)
    eig = [np.linalg.eigvals(reduced_matrix(f, N)) for f in forms]
    return SurfaceResult(N, np.linalg.inv(Xv), max(float(e.real.max()) for e in eig),
                         max(float(np.abs(e).max()) for e in eig), str(prob.status), solver)


def lyapunov_p2(Phi: Mat) -> Mat:
    """``P_2`` with ``P_2 Phi + Phi^T P_2 = -I_l`` (Chen2020 eq. 45); Phi must be Hurwitz."""
    if np.max(np.linalg.eigvals(Phi).real) >= 0.0:
        raise ValueError("Phi must be Hurwitz (Chen2020 eq. 42)")
    P2 = scipy.linalg.solve_continuous_lyapunov(Phi.T, -np.eye(Phi.shape[0]))
    return np.asarray(0.5 * (P2 + P2.T), dtype=np.float64)


def _fault_directions(form: TrackingForm, faulty: Sequence[int],
                      C_c: Mat) -> tuple[Mat, Mat, Mat]:
    """``H~_p = T_c [0; H_p]`` (eq. 34), ``H~_c = [C_c H_p; 0]`` (eq. 28) and ``H_p``."""
    l_ = form.B_2.shape[0]
    n = form.A_t.shape[0] - l_
    Hp = np.zeros((n, len(faulty)))
    for j, i in enumerate(faulty):
        Hp[i, j] = 1.0
    Ht = form.T_c @ np.vstack([np.zeros((l_, len(faulty))), Hp])
    Hc = np.vstack([C_c @ Hp, np.zeros((n, len(faulty)))])
    return Ht, Hc, Hp


def sliding_blocks(forms: Sequence[TrackingForm], N: Mat, faulty: Sequence[int], M_p: Mat,
                   C_c: Mat) -> list[ClosedLoopBlock]:
    """Per vertex, the controller's sliding motion (Chen2020 eq. 51) as a closed loop driven by
    the fault-estimation error ``e_f`` and the uncertainty ``xi``, with output ``x_p``
    (eqs. 54-57).

    With the corrected state ``x^ = x~ - H~_p e_f`` (eq. 24 in the regular form; eq. 34 prints
    the opposite sign) and ``H~_p`` in the ``x^_2`` rows (a faulty rate sensor), during sliding
    ``x^_2 = -N x^_1`` and

        x^_1' = A^s_11 x^_1 + [A~_c H~_p + H~_c]_1 e_f + M~_c1 xi + B~_r1 r,
        x_p = [0 T_n^{-1}] [I; -N] x^_1 + H_p e_f.
    """
    out = []
    l_ = N.shape[0]
    for f in forms:
        n1 = f.n1
        Ht, Hc, Hp = _fault_directions(f, faulty, C_c)
        if np.any(Ht[:n1] != 0.0):
            raise ValueError("the faulty sensor must be one of the virtual-control states "
                             "(x^_2): otherwise e_f' enters the sliding motion")
        n = f.A_t.shape[0] - l_
        Mc = f.T_c @ np.vstack([np.zeros((l_, M_p.shape[1])), M_p])
        Tn_inv = np.linalg.inv(f.T_c[l_:, l_:])
        C = np.asarray(Tn_inv @ np.vstack([np.eye(n1), -N])[l_:], dtype=np.float64)  # eq. 57
        assert C.shape == (n, n1)
        out.append(ClosedLoopBlock(reduced_matrix(f, N), (f.A_t @ Ht + Hc)[:n1], Mc[:n1], C,
                                   Hp))
    return out


def modulation_terms(A_vertices: Sequence[Mat], forms: Sequence[TrackingForm], N: Mat,
                     faulty: Sequence[int], A_f: Mat, L1: Mat, M_p: Mat,
                     C_c: Mat) -> tuple[float, float]:
    """``m = max ||S M^||`` and ``h = max ||S H^||`` over the vertices (Chen2020 eq. 46), with
    (eq. 38, our signs: see :func:`sliding_blocks`)

        H^ = -(A~_c H~_p + H~_c) E + H~_p E A~_11,  M^ = M~_c - H~_p E M~_1,
        E = A_f^{-1} A_212, A~_11 = A_11 + L_1 A_211, M~_1 = M_1 + L M_2.
    """
    S = np.hstack([N, np.eye(N.shape[0])])
    A_f = np.atleast_2d(A_f)
    L1 = np.atleast_2d(L1)
    n = A_vertices[0].shape[0]
    perm = list(faulty) + [i for i in range(n) if i not in faulty]
    q = len(faulty)
    Mperm = M_p[perm]
    Mt1 = Mperm[:q] + L1 @ Mperm[q:]
    m = h = 0.0
    l_ = N.shape[0]
    for Ap, f in zip(A_vertices, forms, strict=True):
        blk = partition(Ap, faulty, A_f)
        E = np.linalg.solve(A_f, blk["A212"])
        At11 = blk["A11"] + L1 @ blk["A211"]
        Ht, Hc, _ = _fault_directions(f, faulty, C_c)
        Mc = f.T_c @ np.vstack([np.zeros((l_, M_p.shape[1])), M_p])
        Hh = -(f.A_t @ Ht + Hc) @ E + Ht @ E @ At11
        Mh = Mc - Ht @ E @ Mt1
        m = max(m, float(np.linalg.norm(S @ Mh, 2)))
        h = max(h, float(np.linalg.norm(S @ Hh, 2)))
    return m, h
