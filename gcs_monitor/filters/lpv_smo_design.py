"""LMI design of the LPV sliding-mode observer's gain ``L_1`` (Chen2020 Assumption 3.1 and
sec. IV's bounded-real-lemma condition), solved with cvxpy.

During sliding the fault-estimation error obeys (Chen2020 eq. 22)

    e~_1' = A~_11(rho) e~_1 - M~_1(rho) xi,   A~_11 = A_11 + L_1 A_211,  M~_1 = M_1 + L M_2,
    e_f = -A_f^{-1} A_212 e~_1 = -e~_1

(``A_212 = A_f``). Two designs share one LMI family, at the vertices of Omega (the matrices are
affine in rho, rho_1 and rho_2 independent, so vertex conditions with a common Lyapunov matrix
hold on the whole box):

* **observer** (no controller): the bounded real lemma on the map ``xi -> e_f`` above, with
  ``P_1 > 0`` and ``Y = P_1 L_1`` (a change of variables that makes the products linear);
  stability of ``A~_11`` at every vertex is Assumption 3.1 (eq. 12);
* **closed loop** (Chen2020 eqs. 52-58 with the caller's controller): the controller's closed
  loop ``x_c' = A_c x_c + H_c e_f + M_c xi``, ``x_p = C_c x_c`` driven by the corrected
  measurement, coupled with the observer error above; the bounded real lemma on ``xi -> x_p``
  with ``P = diag(P_c, P_1)`` gives the L2-gain bound whose inverse is the cone bound c_1 of the
  uncertainty (Chen2020 reports 1.2918 for MuPAL-alpha with its sliding-mode controller). With
  the closed loop not affine in rho (a gain-scheduled autopilot), the caller grids the speed
  range instead of using vertices; the bound then holds on the grid (quadratic stability with a
  common P).

``P_1 = p_1 I_q`` (q = 1 in every case here, so no restriction) lets ``||L_1|| <= l1_max`` be
written ``||Y|| <= l1_max p_1``: without a bound the observer design pushes ``L_1`` to infinity
(a larger ``L_1`` always shortens the error's time constant), which amplifies measurement noise
through ``G_n = [-L; I]``.

Solver: Clarabel (interior point: 1e-8 accuracy, deterministic), SCS as a fallback.
"""

from __future__ import annotations

import importlib
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from gcs_monitor.core.types import Mat
from gcs_monitor.filters.lpv_smo import partition


@dataclass(frozen=True, slots=True)
class ClosedLoopBlock:
    """The controller's closed loop at one scheduling point, for the design of Chen2020
    eq. 58: ``x_c' = A_c x_c + H_c e_f + M_c xi``, ``x_p = C_c x_c + D_f e_f`` (``D_f``: the
    sliding-mode controller's reduced-order motion, where the corrected rate is a state of the
    sliding surface, Chen2020 eq. 57; None = 0)."""

    A_c: Mat  # (nc, nc)
    H_c: Mat  # (nc, q)
    M_c: Mat  # (nc, k)
    C_c: Mat  # (n, nc)
    D_f: Mat | None = None  # (n, q)


@dataclass(frozen=True, slots=True)
class LmiResult:
    L1: Mat  # (q, n-q)
    p1: float
    gamma: float  # L2-gain bound (observer: xi -> e_f; closed loop: xi -> x_p)
    status: str
    solver: str


def he(X: Any) -> Any:
    """``He(X) = X + X^T`` of a cvxpy expression or an array."""
    return X + X.T


def solve(prob: Any, solver: str) -> str:
    """Solve a cvxpy problem with ``solver`` (Clarabel), SCS when it gives up; the solver used."""
    cp: Any = importlib.import_module("cvxpy")
    try:
        prob.solve(solver=solver)
    except cp.error.SolverError:  # Clarabel gave up: the first-order solver
        solver = "SCS"
        prob.solve(solver=solver, eps=1e-9, max_iters=200_000)
    return solver


def design_l1(A_vertices: Sequence[Mat], faulty: Sequence[int], A_f: Mat, M_p: Mat, *,
              l1_max: float, closed_loop: Sequence[ClosedLoopBlock] | None = None,
              decay: float = 0.0, L1_fixed: Mat | None = None,
              solver: str = "CLARABEL") -> LmiResult:
    """Minimise the L2-gain bound gamma over ``L_1`` (see the module docstring).

    Parameters
    ----------
    A_vertices : ``A_p`` at the vertices (or grid points) of Omega, each (n, n)
    faulty : the faulty outputs (the columns of ``H_p``)
    A_f : (q, q) output filter
    M_p : (n, k) uncertainty distribution (Chen2020 eq. 60 uses ``[0_{2x2} I_2]^T``)
    l1_max : bound on ``||L_1||`` (spectral norm)
    closed_loop : per point of ``A_vertices``, the controller's closed loop; None: observer only
    decay : minimum decay rate of ``A~_11`` (1/s), 0 = stability only
    L1_fixed : analysis instead of synthesis: the bound of this ``L_1`` (``Y = p_1 L_1``)
    """
    cp: Any = importlib.import_module("cvxpy")  # optional (design extra); untyped use

    n = A_vertices[0].shape[0]
    q = len(faulty)
    A_f = np.atleast_2d(A_f)
    perm = list(faulty) + [i for i in range(n) if i not in faulty]
    Mperm = M_p[perm]
    M1, M2 = Mperm[:q], Mperm[q:]  # M2 here: the rows of the non-faulty states
    k = M_p.shape[1]
    p1 = cp.Variable(nonneg=True)
    Y = cp.Variable((q, n - q)) if L1_fixed is None else p1 * np.atleast_2d(L1_fixed)
    g = cp.Variable(nonneg=True)
    eps = 1e-7
    cons = [p1 >= eps, cp.norm(Y, "fro") <= l1_max * p1]  # = spectral for q = 1
    Iq = np.eye(q)
    out_f = -np.linalg.solve(A_f, partition(A_vertices[0], faulty, A_f)["A212"])  # e_f map
    Pc = None
    if closed_loop is not None:
        nc = closed_loop[0].A_c.shape[0]
        Pc = cp.Variable((nc, nc), symmetric=True)
        cons.append(Pc >> eps * np.eye(nc))
    for i, Ap in enumerate(A_vertices):
        blk = partition(Ap, faulty, A_f)
        PA11 = p1 * blk["A11"] + Y @ blk["A211"]  # P_1 A~_11
        PM1 = p1 * M1 + Y @ M2  # P_1 M~_1
        if decay > 0.0:
            cons.append(he(PA11) + 2.0 * decay * p1 * Iq << 0)
        if closed_loop is None:
            # BRL on xi -> e_f: [[He(P A), -P M, C^T], [., -g I, 0], [C, 0, -g I]] < 0
            lmi = cp.bmat([
                [he(PA11), -PM1, out_f.T],
                [-PM1.T, -g * np.eye(k), np.zeros((k, q))],
                [out_f, np.zeros((q, k)), -g * Iq]])
        else:
            cl = closed_loop[i]
            assert Pc is not None
            # state [x_c; e~_1], e_f = out_f e~_1; xi enters x_c by M_c and e~_1 by -M~_1
            top = Pc @ cl.A_c
            cross = Pc @ cl.H_c @ out_f  # (nc, q)
            Df = (cl.D_f @ out_f if cl.D_f is not None
                  else np.zeros((cl.C_c.shape[0], q)))  # x_p's direct term in e~_1
            lmi = cp.bmat([
                [he(top), cross, Pc @ cl.M_c, cl.C_c.T],
                [cross.T, he(PA11), -PM1, Df.T],
                [(Pc @ cl.M_c).T, -PM1.T, -g * np.eye(k), np.zeros((k, cl.C_c.shape[0]))],
                [cl.C_c, Df, np.zeros((cl.C_c.shape[0], k)),
                 -g * np.eye(cl.C_c.shape[0])]])
        sym = 0.5 * (lmi + lmi.T)
        cons.append(sym << -eps * np.eye(sym.shape[0]))
    prob = cp.Problem(cp.Minimize(g), cons)
    solver = solve(prob, solver)
    if p1.value is None or g.value is None:
        return LmiResult(np.full((q, n - q), math.nan), math.nan, math.nan, str(prob.status),
                         solver)
    L1 = (np.asarray(Y.value) / float(p1.value) if L1_fixed is None
          else np.atleast_2d(np.asarray(L1_fixed, dtype=np.float64)))
    return LmiResult(L1, float(p1.value), float(g.value), str(prob.status), solver)


def a11_margin(A_p: Mat, faulty: Sequence[int], A_f: Mat, L1: Mat) -> float:
    """Largest real part of the eigenvalues of ``A~_11 = A_11 + L_1 A_211`` at one ``A_p``
    (negative: Assumption 3.1 holds there), 1/s."""
    blk = partition(A_p, faulty, np.atleast_2d(A_f))
    At = blk["A11"] + np.atleast_2d(L1) @ blk["A211"]
    return float(np.max(np.linalg.eigvals(At).real))
