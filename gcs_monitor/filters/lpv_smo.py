"""LPV sliding-mode observer for sensor-fault reconstruction (Chen2020 sec. III, eqs. 1-22).

Plant (eq. 1): ``x_p' = A_p(rho) x_p + B_p(rho) u_p + c_p(rho) + M_p xi``,
``y_p = x_p + H_p f`` with the columns of ``H_p`` from the standard basis (the ``faulty``
outputs). The observer knows nothing about aircraft: it takes the affine stacks of
``A_p, B_p, c_p`` (``A_p(rho) = A_0 + rho_1 A_1 + rho_2 A_2``) and the design of
:class:`SmoDesign`.

Coordinates, as implemented (eqs. 2-5 and 13):

* ``T_s`` permutes the state so that the q faulty states come first; then
  ``C_1 T_s^{-1} = [0 I_{n-q}]`` (eq. 4);
* the output filter ``z_f' = -A_f z_f + A_f y_p2`` (eq. 3) augments the state:
  ``x_a = [T_s x_p; z_f]``, ``y = [y_p1; z_f] = C x_a`` with ``C = [0 I_n]`` and the fault
  entering through ``D = [0; A_f]`` (eq. 5);
* ``A(rho)`` is partitioned with ``A_11`` (q x q), ``A_21 = [A_211; A_212]`` (eq. 9), and
  ``A_212 = A_f`` (the filter row of the augmented system);
* gains (eq. 10): ``G_l = [A_11 L - A_12 + k_2 L; -A_22 + A_21 L - k_2 I]``,
  ``G_n = [-L; I_n]``, ``L = [L_1 0]`` (eq. 11).

Then ``T_L (A + G_l C) T_L^{-1} = [[A_11 + L_1 A_211, 0], [A_21, -k_2 I]]`` (the error
dynamics of eq. 14 are block triangular), the injection enters only the ``e_y`` rows and the
fault only ``e_y`` (``L D = 0`` because of the zero block of ``L``).

Injection (eq. 7) with the sigmoid smoothing of Chen2020 sec. V (Edwards & Spurgeon):
``nu = -k e_y / (||e_y|| + delta)``, ``e_y = C z - y`` (estimate minus measurement). The fault
estimate is the equivalent output injection through ``W = [0 A_f^{-1}]`` (eq. 21): the smoothed
``nu`` *is* the equivalent injection inside the boundary layer, so ``f_hat = A_f^{-1} nu_f``
(``nu_f`` the filter rows of ``nu``). During sliding ``e_f = f_hat - f = -A_f^{-1} A_212 e~_1 =
-e~_1`` (eq. 22): the fault estimation error is the (transformed) estimation error of the faulty
state.

Discretisation: explicit Euler at the step given (Chen2020 sec. VI: explicit Euler at 50 Hz), in
the numba kernel of ``filters/_lpv_smo_jit.py``; its numpy reference is
``tests/reference/lpv_smo.py``.

Sign convention of the paper (eq. 6): ``e_y = C(z - x_a)``; eq. 7 then drives ``e_y`` to zero.
The paper's eq. 22 prints ``A~_11 e~_1 - M~_1 xi e_f = ...``: two equations run together; read
as ``e~_1' = A~_11 e~_1 - M~_1 xi`` and ``e_f = -A_f^{-1} A_212 e~_1``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from gcs_monitor.core.kernels import load_kernels
from gcs_monitor.core.types import Mat, Vec


@dataclass(frozen=True, slots=True)
class SmoDesign:
    """The observer's design (Chen2020 secs. III and V).

    Attributes
    ----------
    faulty : indices of the possibly faulty outputs in ``x_p`` (the columns of ``H_p``)
    A_f : (q, q) s.p.d. output filter matrix (eq. 3; Chen2020 sec. V: 0.01), 1/s
    k2 : positive scalar of eq. 10 (Chen2020: 0.1), 1/s
    L1 : (q, n-q) the design freedom of eq. 11, in the order of the non-faulty states
    k : modulation gain of eq. 7 (Chen2020 flew 0.8), units of ``e_y``/s
    delta : sigmoid smoothing of eq. 7 (Chen2020: 0.01), units of ``e_y``
    gamma : L2-gain bound of the LMI design (see ``lpv_smo_design``), NaN if not designed
    """

    faulty: tuple[int, ...]
    A_f: Mat
    k2: float
    L1: Mat
    k: float
    delta: float
    gamma: float = math.nan

    def to_dict(self) -> dict[str, Any]:
        return {"faulty": list(self.faulty), "A_f": np.atleast_2d(self.A_f).tolist(),
                "k2": self.k2, "L1": np.atleast_2d(self.L1).tolist(), "k": self.k,
                "delta": self.delta, "gamma": self.gamma}

    @staticmethod
    def from_dict(d: dict[str, Any]) -> SmoDesign:
        return SmoDesign(tuple(int(i) for i in d["faulty"]),
                         np.atleast_2d(np.asarray(d["A_f"], dtype=np.float64)),
                         float(d["k2"]), np.atleast_2d(np.asarray(d["L1"], dtype=np.float64)),
                         float(d["k"]), float(d["delta"]), float(d.get("gamma", math.nan)))


def permutation(n: int, faulty: Sequence[int]) -> list[int]:
    """Row order of ``T_s``: the faulty states first, then the others in their order."""
    f = list(faulty)
    if len(set(f)) != len(f) or not all(0 <= i < n for i in f) or not 0 < len(f) < n:
        raise ValueError(f"faulty outputs {f} must be 1..n-1 distinct indices of 0..{n - 1}")
    return f + [i for i in range(n) if i not in f]


def partition(A_p: Mat, faulty: Sequence[int], A_f: Mat) -> dict[str, Mat]:
    """The blocks of eqs. 8-9 of the augmented, permuted system for one ``A_p``:
    ``A11`` (q,q), ``A12`` (q,n), ``A21`` (n,q), ``A22`` (n,n), ``A211`` (n-q,q), ``A212``
    (q,q)."""
    n = A_p.shape[0]
    q = len(faulty)
    perm = permutation(n, faulty)
    Ap = A_p[np.ix_(perm, perm)]
    A = np.zeros((n + q, n + q))
    A[:n, :n] = Ap
    A[n:, :q] = A_f  # z_f' = A_f y_p2 - A_f z_f, y_p2 = the faulty states
    A[n:, n:] = -A_f
    return {"A": A, "A11": A[:q, :q], "A12": A[:q, q:], "A21": A[q:, :q], "A22": A[q:, q:],
            "A211": A[q:n, :q], "A212": A[n:, :q]}


@dataclass(frozen=True, slots=True)
class SmoMatrices:
    """Affine stacks of the observer, ``X(rho) = X_0 + rho_1 X_1 + rho_2 X_2``.

    ``z' = F z + Gu u + Gy y + c + G_n nu`` with ``F = A + G_l C``, ``Gy = -G_l``, ``y = [y_p1;
    z_f]`` (eq. 6 rearranged). ``W`` (n+q+m+n+1 columns) packs ``[F | Gu | Gy | c]`` so one
    matrix-vector product per step gives the drift.
    """

    n: int
    q: int
    m: int
    perm: tuple[int, ...]
    W: Mat  # (3, n+q, n+q + m + n + 1)
    Gn: Mat  # (n+q, n)
    A_f: Mat  # (q, q)
    A_f_inv: Mat
    k: float
    delta: float
    design: SmoDesign = field(repr=False)
    perm_arr: np.ndarray = field(init=False, repr=False)  # int64 copy of perm for the kernel

    def __post_init__(self) -> None:
        object.__setattr__(self, "perm_arr", np.array(self.perm, dtype=np.int64))


def smo_matrices(A: Mat, B: Mat, c: Mat, design: SmoDesign) -> SmoMatrices:
    """The observer of ``design`` for the plant stacks ``A`` (3, n, n), ``B`` (3, n, m),
    ``c`` (3, n)."""
    n, m = A.shape[1], B.shape[2]
    q = len(design.faulty)
    perm = permutation(n, design.faulty)
    A_f = np.atleast_2d(design.A_f).astype(np.float64)
    L1 = np.atleast_2d(design.L1).astype(np.float64)
    if A_f.shape != (q, q) or L1.shape != (q, n - q):
        raise ValueError(f"A_f {A_f.shape}, L1 {L1.shape}: expected ({q},{q}), ({q},{n - q})")
    L = np.hstack([L1, np.zeros((q, q))])  # eq. 11
    C = np.hstack([np.zeros((n, q)), np.eye(n)])
    W = np.zeros((3, n + q, n + q + m + n + 1))
    for j in range(3):
        # the filter rows (A_212 = A_f, -A_f) and the k_2 terms belong to the constant part
        Aj = partition(A[j], design.faulty, A_f if j == 0 else np.zeros((q, q)))["A"]
        A11, A12, A21, A22 = Aj[:q, :q], Aj[:q, q:], Aj[q:, :q], Aj[q:, q:]
        k2 = design.k2 if j == 0 else 0.0
        Gl = np.vstack([A11 @ L - A12 + k2 * L, -A22 + A21 @ L - k2 * np.eye(n)])  # eq. 10
        F = Aj + Gl @ C
        W[j, :, :n + q] = F
        W[j, :n, n + q:n + q + m] = B[j][perm]
        W[j, :, n + q + m:n + q + m + n] = -Gl
        W[j, :n, -1] = c[j][perm]
    Gn = np.vstack([-L, np.eye(n)])  # eq. 10
    return SmoMatrices(n, q, m, tuple(perm), W, Gn, A_f,
                       np.asarray(np.linalg.inv(A_f), dtype=np.float64), design.k,
                       design.delta, design)


@dataclass(frozen=True, slots=True)
class SmoState:
    """Observer state: ``z`` (n+q) estimates ``x_a = [T_s x_p; z_f]``; ``z_f`` (q) is the
    output filter of eq. 3 run on the measured ``y_p2``."""

    z: Vec
    z_f: Vec


@dataclass(frozen=True, slots=True)
class SmoOutput:
    """One observer step's outputs (at the step's start instant).

    f_hat : (q,) fault estimate (eq. 21)
    x_hat : (n,) state estimate, original order (the faulty states from the model)
    e_y : (n,) output estimation error ``C z - y``
    nu : (n,) injection (eq. 7, smoothed)
    """

    f_hat: Vec
    x_hat: Vec
    e_y: Vec
    nu: Vec


def smo_init(mats: SmoMatrices, y_p: Vec, f0: Vec | None = None) -> SmoState:
    """Start at the measurement corrected by a fault guess ``f0`` (zero by default):
    ``z = [T_s y_p - [f0; 0]; y_p2]``, ``z_f = y_p2`` (Chen2020 sec. V: a good initial guess
    keeps ``e_1(0)`` small; during sliding ``e_f = -e~_1``, so starting the faulty states at
    ``y_p2 - f0`` starts the fault estimate's error at ``f - f0``)."""
    y = np.asarray(y_p, dtype=np.float64)[list(mats.perm)]
    y2 = y[:mats.q]
    x0 = y.copy()
    if f0 is not None:
        x0[:mats.q] -= np.asarray(f0, dtype=np.float64)
    return SmoState(np.concatenate([x0, y2]), y2.copy())


def smo_step(s: SmoState, mats: SmoMatrices, y_p: Vec, u: Vec, rho: tuple[float, float],
             dt_s: float) -> tuple[SmoState, SmoOutput]:
    """One explicit-Euler step of eqs. 3, 6, 7 and 21 (the numba kernel of
    ``filters/_lpv_smo_jit.py``).

    Parameters
    ----------
    s : state at t_k
    y_p : (n,) measured outputs at t_k, original order
    u : (m,) inputs at t_k
    rho : scheduling parameter at t_k
    dt_s : step to t_{k+1}

    Returns
    -------
    the state at t_{k+1} and the outputs at t_k
    """
    kern = load_kernels("gcs_monitor.filters._lpv_smo_jit")
    n, q = mats.n, mats.q
    z_next = np.empty(n + q)
    zf_next = np.empty(q)
    f_hat = np.empty(q)
    x_hat = np.empty(n)
    e_y = np.empty(n)
    nu = np.empty(n)
    kern.smo_step(s.z, s.z_f, mats.W, mats.Gn, mats.A_f, mats.A_f_inv, mats.perm_arr, mats.k,
                  mats.delta, np.asarray(y_p, dtype=np.float64), np.asarray(u, dtype=np.float64),
                  float(rho[0]), float(rho[1]), float(dt_s), z_next, zf_next, f_hat, x_hat, e_y,
                  nu, np.empty(mats.W.shape[2]))
    return SmoState(z_next, zf_next), SmoOutput(f_hat, x_hat, e_y, nu)


def error_dynamics(A_p: Mat, design: SmoDesign) -> Mat:
    """``A~_e = T_L (A + G_l C) T_L^{-1}`` of eq. 14 at one ``A_p`` (for stability checks:
    its eigenvalues are those of ``A_11 + L_1 A_211`` and ``-k_2``)."""
    n = A_p.shape[0]
    q = len(design.faulty)
    A_f = np.atleast_2d(design.A_f)
    blk = partition(A_p, design.faulty, A_f)
    L = np.hstack([np.atleast_2d(design.L1), np.zeros((q, q))])
    C = np.hstack([np.zeros((n, q)), np.eye(n)])
    A11, A12, A21, A22 = blk["A11"], blk["A12"], blk["A21"], blk["A22"]
    Gl = np.vstack([A11 @ L - A12 + design.k2 * L, -A22 + A21 @ L - design.k2 * np.eye(n)])
    TL = np.block([[np.eye(q), L], [np.zeros((n, q)), np.eye(n)]])
    return TL @ (blk["A"] + Gl @ C) @ np.linalg.inv(TL)
