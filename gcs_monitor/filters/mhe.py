"""Real-time constrained moving horizon estimation (Wan2018 sec. III-B and V).

Problem (Wan2018 eqs. 21-22), horizon of ``N`` output samples ``l = k - N + 1 .. k``::

    min  1/2 |x_l - x_l^-|^2_{P^-1} + 1/2 sum_{i=l}^{k-1} |u_i|^2_{Q^-1}
         + 1/2 sum_{i=l}^{k} |y_i - h(x_i, Theta_i)|^2_{R^-1}
    s.t. x_{i+1} = F(x_i, u_i, Theta_i),  u_LB <= u_i <= u_UB,  x_LB <= x_i <= x_UB

Solved in real time exactly as Wan2018 sec. V:

* one generalised Gauss-Newton SQP iteration per sample, linearised around the shifted
  previous solution (real-time iteration, eq. 42);
* each QP solved by an infeasible-start primal barrier interior-point method with a
  backtracking line search and a fixed number of iterations (Algorithm 1,
  ``n_kappa = n_QP = 2``);
* each search direction from a Riccati recursion on the equivalent equality-constrained
  linear MHE (Algorithm 2, eqs. 45-46);
* deterministic arrival cost: ``x_l^- = x_hat_{l|k-1}``, fixed ``P`` (sec. III-B).

The unconstrained MHE (UMHE) is the same solver with the barrier terms switched off.

Corrections to the printed equations (all checked by tests/gcs_monitor/filters/test_mhe.py):

* eq. 42: ``f_i = F(x_hat_i, u_hat_i, Theta_i) - x_hat_{i+1}`` (the printed
  ``x_hat_i - x_hat_{i+1} + t_s F`` mixes the continuous and the discrete F).
* eq. 46d/Alg. 2 line 14: the minimiser of the barrier-augmented input term is
  ``Q_bar [Q^-1 (r_u - du^-) - kappa g_u]``; the printed ``r_bar_u`` lacks the ``Q_bar``
  factor, which the dense-KKT test exposes. We set ``r_bar_u`` to the minimiser.
* eq. 46e: ``C_i dx_i^-`` (printed ``C_i dx_l^-``).
* Alg. 1: kappa is divided by 10 after every ``n_QP`` iterations (so that there are
  ``n_kappa`` values of kappa); the printed "j an integral multiple of n_kappa" at j = 0
  would shrink kappa after the first iteration.
* Eq. 21a prints the input sum twice (i = l..k-1 and l..k); only l..k-1 has inputs.

The solver runs in the numba kernels of ``filters/_mhe_jit.py``; the numpy reference that the
equivalence test compares them with (and that the dense-KKT and box-QP tests check) is
``tests/reference/mhe.py``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from gcs_monitor.core.kernels import load_kernels
from gcs_monitor.core.types import Mat, Vec


class MheModel(Protocol):
    """Discrete model x+ = f(x, u, theta, dt), y = h(x, theta) with Jacobians.

    A model may also offer ``linearise_horizon(n, x_lin, u_lin, th, dts, ym, mk, a, b, f, cm,
    ry) -> bool``, a compiled version of :func:`_linearise` (returning False when it cannot
    run); the compiled :func:`mhe_step` then uses it instead of 3 n - 2 method calls
    (``models.airdata.AirDataModel.linearise_horizon``).
    """

    @property
    def n_x(self) -> int: ...
    @property
    def n_u(self) -> int: ...
    @property
    def n_y(self) -> int: ...

    def f(self, x: Vec, u: Vec, theta_p: Vec, dt_s: float) -> Vec: ...
    def f_jac_x(self, x: Vec, u: Vec, theta_p: Vec, dt_s: float) -> Mat: ...
    def f_jac_u(self, x: Vec, u: Vec, theta_p: Vec, dt_s: float) -> Mat: ...
    def h(self, x: Vec, theta_p: Vec) -> Vec: ...
    def h_jac_x(self, x: Vec, theta_p: Vec) -> Mat: ...


@dataclass(frozen=True, slots=True)
class MheWeights:
    """Diagonals of P, Q, R (Wan2018 eq. 22), in the units of x, u, y squared."""

    p_diag: Vec
    q_diag: Vec
    r_diag: Vec


@dataclass(frozen=True, slots=True)
class MheBounds:
    """Box bounds on states and unknown inputs (Wan2018 eq. 21b); +-inf where unbounded.

    The bounds may change per flight condition: pass a new instance to :func:`mhe_step`.
    """

    x_lb: Vec
    x_ub: Vec
    u_lb: Vec
    u_ub: Vec

    @staticmethod
    def unbounded(n_x: int, n_u: int) -> MheBounds:
        inf_x, inf_u = np.full(n_x, np.inf), np.full(n_u, np.inf)
        return MheBounds(-inf_x, inf_x.copy(), -inf_u, inf_u.copy())


@dataclass(frozen=True, slots=True)
class IpSettings:
    """Primal barrier IP settings (Wan2018 Algorithm 1 and sec. V-C).

    ``n_kappa = n_qp = 2`` are Wan2018's values. ``kappa_init`` and ``n_s_max`` are not given
    in Wan2018; our choices, see docs/papers-notes.md.
    """

    n_kappa: int = 2
    n_qp: int = 2
    kappa_init: float = 1.0e-2
    kappa_factor: float = 0.1  # Wan2018 Algorithm 1
    n_s_max: int = 12
    constrained: bool = True  # False: UMHE (barrier terms off)


@dataclass(frozen=True, slots=True)
class MheState:
    """Horizon solution after the last sample (arrays are never modified in place).

    Attributes
    ----------
    x : (N, n_x) x_hat_{i|k}, i = l..k (only the last ``n`` rows are filled)
    u : (N-1, n_u) u_hat_{i|k}, i = l..k-1
    theta : (N, n_theta) measured parameters per node
    dt_s : (N,) interval from node i to node i+1 (last entry unused)
    y : (N, n_y) measurements per node
    y_mask : (N, n_y) 1 where the output row is used, 0 where its row of C is zeroed (sec. V-C)
    n : number of filled nodes (< N during the start-up)
    """

    x: Mat
    u: Mat
    theta: Mat
    dt_s: Vec
    y: Mat
    y_mask: Mat
    n: int


@dataclass(frozen=True, slots=True)
class MheInfo:
    """Diagnostics of one real-time iteration."""

    step_sizes: Vec  # (n_kappa n_qp,) line-search steps s_j
    n_active: int  # bound entries within 1 % of their range of a bound
    numerics_ok: bool


def mhe_init(x0: Vec, y0: Vec, y_mask0: Vec, theta0: Vec, horizon_n: int, n_u: int) -> MheState:
    """Start a horizon with one node at ``x0`` (its arrival prior)."""
    n_x, n_y, n_th = x0.size, y0.size, theta0.size
    x = np.zeros((horizon_n, n_x))
    th = np.zeros((horizon_n, n_th))
    y = np.zeros((horizon_n, n_y))
    m = np.zeros((horizon_n, n_y))
    x[0], th[0], y[0], m[0] = x0, theta0, y0, y_mask0
    return MheState(
        x=x,
        u=np.zeros((max(horizon_n - 1, 0), n_u)),
        theta=th,
        dt_s=np.zeros(horizon_n),
        y=y,
        y_mask=m,
        n=1,
    )


def mhe_predict(s: MheState, model: MheModel, dt_s: float) -> Vec:
    """One-step-ahead prediction x_hat_{k+1|k} = F(x_hat_{k|k}, 0, Theta_k) (Wan2018 eq. 29)."""
    j = s.n - 1
    return model.f(s.x[j], np.zeros(model.n_u), s.theta[j], dt_s)


def mhe_step(
    s: MheState,
    model: MheModel,
    y: Vec,
    y_mask: Vec,
    theta_p: Vec,
    dt_s: float,
    weights: MheWeights,
    bounds: MheBounds,
    ip: IpSettings,
    *,
    x_node: Vec | None = None,
) -> tuple[MheState, MheInfo]:
    """Shift the horizon by one sample and do one real-time GGN-SQP iteration (Wan2018 sec. V).

    Parameters
    ----------
    s : solution over the previous horizon [l-1, k-1]
    y : (n_y,) measurements at k (entries with ``y_mask == 0`` are ignored, may be NaN)
    y_mask : (n_y,) 1 to use the output, 0 to zero its row of C_i (Wan2018 sec. V-C)
    theta_p : measured parameters Theta_k
    dt_s : t_s between samples k-1 and k
    x_node : x_hat_{k|k-1} when the caller has it already (:func:`mhe_predict` of ``s`` and
        ``dt_s``); computed here otherwise

    The step runs through the kernels of ``filters/_mhe_jit.py``: shift, the model's
    linearisation (its compiled ``linearise_horizon``, else :func:`_linearise`), QP, result.
    """
    kern = load_kernels("gcs_monitor.filters._mhe_jit")
    big_n = s.x.shape[0]
    n_x, n_u, n_y = model.n_x, model.n_u, model.n_y
    # x_hat_{k|k-1} = F(x_hat_{k-1|k-1}, 0, Theta_{k-1}), appended by the shift
    if x_node is None:
        x_node = mhe_predict(s, model, dt_s)
    x_lin = np.empty_like(s.x)
    u_lin = np.empty_like(s.u)
    th = np.empty_like(s.theta)
    dts = np.empty_like(s.dt_s)
    ym = np.empty_like(s.y)
    mk = np.empty_like(s.y_mask)
    n = kern.shift(
        s.x, s.u, s.theta, s.dt_s, s.y, s.y_mask, s.n, x_node, y, y_mask, theta_p, float(dt_s),
        bounds.x_lb, bounds.x_ub, bounds.u_lb, bounds.u_ub, ip.constrained,
        x_lin, u_lin, th, dts, ym, mk,
    )  # fmt: skip
    m1 = max(big_n - 1, 0)
    a = np.zeros((m1, n_x, n_x))
    b = np.zeros((m1, n_x, n_u))
    f = np.zeros((m1, n_x))
    cm = np.zeros((big_n, n_y, n_x))
    ry = np.zeros((big_n, n_y))
    lin = getattr(model, "linearise_horizon", None)
    if lin is None or not lin(n, x_lin, u_lin, th, dts, ym, mk, a, b, f, cm, ry):
        _linearise(model, n, x_lin, u_lin, th, dts, ym, mk, a, b, f, cm, ry)
    x_new = np.empty_like(x_lin)
    u_new = np.empty_like(u_lin)
    steps = np.zeros(ip.n_kappa * ip.n_qp)
    ok, n_active = kern.rti_solve(
        n, weights.p_diag, weights.q_diag, weights.r_diag, a, b, cm, f, ry, x_lin, u_lin,
        bounds.x_lb, bounds.x_ub, bounds.u_lb, bounds.u_ub, ip.constrained,
        ip.n_kappa, ip.n_qp, ip.kappa_init, ip.kappa_factor, ip.n_s_max, x_new, u_new, steps,
    )  # fmt: skip
    new = MheState(x=x_new, u=u_new, theta=th, dt_s=dts, y=ym, y_mask=mk, n=n)
    return new, MheInfo(step_sizes=steps, n_active=int(n_active), numerics_ok=bool(ok))


def _linearise(
    model: MheModel,
    n: int,
    x_lin: Mat,
    u_lin: Mat,
    th: Mat,
    dts: Vec,
    ym: Mat,
    mk: Mat,
    a: Mat,
    b: Mat,
    f: Mat,
    cm: Mat,
    ry: Mat,
) -> None:
    """Wan2018 eq. 42 node by node through the model's methods (writes a, b, f, cm, ry).

    For a model without a compiled ``linearise_horizon``; the one ``AirDataModel`` has fills
    the same arrays in one numba call.
    """
    for i in range(n):
        cm[i] = model.h_jac_x(x_lin[i], th[i]) * mk[i][:, None]
        ry[i] = (ym[i] - model.h(x_lin[i], th[i])) * mk[i]
        if i < n - 1:
            a[i] = model.f_jac_x(x_lin[i], u_lin[i], th[i], dts[i])
            b[i] = model.f_jac_u(x_lin[i], u_lin[i], th[i], dts[i])
            f[i] = model.f(x_lin[i], u_lin[i], th[i], dts[i]) - x_lin[i + 1]
