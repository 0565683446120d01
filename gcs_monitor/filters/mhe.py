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
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from gcs_monitor.core.optional import optional_module
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
    compiled: bool = True  # use the numba kernel when numba is installed (same algorithm)


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
) -> tuple[MheState, MheInfo]:
    """Shift the horizon by one sample and do one real-time GGN-SQP iteration (Wan2018 sec. V).

    Parameters
    ----------
    s : solution over the previous horizon [l-1, k-1]
    y : (n_y,) measurements at k (entries with ``y_mask == 0`` are ignored, may be NaN)
    y_mask : (n_y,) 1 to use the output, 0 to zero its row of C_i (Wan2018 sec. V-C)
    theta_p : measured parameters Theta_k
    dt_s : t_s between samples k-1 and k

    With ``ip.compiled`` and numba installed the step runs through the kernels of
    ``filters/_mhe_jit.py`` (and the model's optional compiled ``linearise_horizon``); otherwise
    through the numpy reference. Both implement the same algorithm.
    """
    kern = compiled_kernel() if ip.compiled else None
    if kern is not None:
        return _step_compiled(kern, s, model, y, y_mask, theta_p, dt_s, weights, bounds, ip)
    return _step_reference(s, model, y, y_mask, theta_p, dt_s, weights, bounds, ip)


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
    """Wan2018 eq. 42 node by node through the model's methods (writes a, b, f, cm, ry)."""
    for i in range(n):
        cm[i] = model.h_jac_x(x_lin[i], th[i]) * mk[i][:, None]
        ry[i] = (ym[i] - model.h(x_lin[i], th[i])) * mk[i]
        if i < n - 1:
            a[i] = model.f_jac_x(x_lin[i], u_lin[i], th[i], dts[i])
            b[i] = model.f_jac_u(x_lin[i], u_lin[i], th[i], dts[i])
            f[i] = model.f(x_lin[i], u_lin[i], th[i], dts[i]) - x_lin[i + 1]


def _step_reference(
    s: MheState,
    model: MheModel,
    y: Vec,
    y_mask: Vec,
    theta_p: Vec,
    dt_s: float,
    weights: MheWeights,
    bounds: MheBounds,
    ip: IpSettings,
) -> tuple[MheState, MheInfo]:
    """Plain numpy implementation of :func:`mhe_step` (the reference for the kernels)."""
    big_n = s.x.shape[0]
    n_x, n_u = model.n_x, model.n_u
    # --- shifting (real-time iteration): drop node l-1, append x_hat_{k|k-1} with u_hat = 0
    x_lin = np.empty_like(s.x)
    u_lin = np.zeros_like(s.u)
    th = np.empty_like(s.theta)
    dts = np.empty_like(s.dt_s)
    ym = np.empty_like(s.y)
    mk = np.empty_like(s.y_mask)
    drop = 1 if s.n == big_n else 0
    n = s.n + 1 - drop
    keep = s.n - drop
    x_lin[:keep] = s.x[drop : s.n]
    u_lin[: max(keep - 1, 0)] = s.u[drop : drop + max(keep - 1, 0)]
    th[:keep] = s.theta[drop : s.n]
    dts[:keep] = s.dt_s[drop : s.n]
    dts[keep - 1] = dt_s
    ym[:keep], mk[:keep] = s.y[drop : s.n], s.y_mask[drop : s.n]
    x_lin[keep] = model.f(s.x[s.n - 1], np.zeros(n_u), s.theta[s.n - 1], dt_s)
    th[keep], ym[keep], mk[keep] = theta_p, np.where(y_mask > 0, y, 0.0), y_mask
    dts[keep] = 0.0
    x_lin[n:] = 0.0

    if ip.constrained:
        # The barrier needs a strictly interior linearisation point; it is interior unless the
        # bounds changed (flight condition) or the start-up guess is outside them.
        x_lin[:n] = _clip_interior(x_lin[:n], bounds.x_lb, bounds.x_ub)
        if n > 1:
            u_lin[: n - 1] = _clip_interior(u_lin[: n - 1], bounds.u_lb, bounds.u_ub)

    # --- linearisation (Wan2018 eq. 42)
    a = np.zeros((big_n - 1, n_x, n_x)) if big_n > 1 else np.zeros((0, n_x, n_x))
    b = np.zeros((big_n - 1, n_x, n_u)) if big_n > 1 else np.zeros((0, n_x, n_u))
    f = np.zeros((max(big_n - 1, 0), n_x))
    cm = np.zeros((big_n, model.n_y, n_x))
    ry = np.zeros((big_n, model.n_y))
    _linearise(model, n, x_lin, u_lin, th, dts, ym, mk, a, b, f, cm, ry)
    ru = -u_lin
    if ip.constrained:
        dxl, dxu = bounds.x_lb - x_lin, bounds.x_ub - x_lin
        dul, duu = bounds.u_lb - u_lin, bounds.u_ub - u_lin
    else:
        dxl = np.full_like(x_lin, -np.inf)
        dxu = np.full_like(x_lin, np.inf)
        dul = np.full_like(u_lin, -np.inf)
        duu = np.full_like(u_lin, np.inf)
    dx, du, steps = barrier_ip_qp(
        n,
        weights.p_diag,
        weights.q_diag,
        weights.r_diag,
        a,
        b,
        cm,
        f,
        ry,
        ru,
        dxl,
        dxu,
        dul,
        duu,
        ip,
    )
    x_new = x_lin + dx
    u_new = u_lin + du
    ok = bool(np.all(np.isfinite(x_new[:n])) and np.all(np.isfinite(u_new[: max(n - 1, 0)])))
    n_active = 0
    if ip.constrained:
        n_active = _count_near_bounds(x_new[:n], bounds.x_lb, bounds.x_ub) + _count_near_bounds(
            u_new[: max(n - 1, 0)], bounds.u_lb, bounds.u_ub
        )
    new = MheState(x=x_new, u=u_new, theta=th, dt_s=dts, y=ym, y_mask=mk, n=n)
    return new, MheInfo(step_sizes=steps, n_active=n_active, numerics_ok=ok)


def _clip_interior(v: Mat, lb: Vec, ub: Vec) -> Mat:
    # Stay a small fraction of the box width inside each finite bound.
    width = np.where(np.isfinite(ub - lb), ub - lb, 0.0)
    margin = width * 1.0e-3
    return np.minimum(np.maximum(v, lb + margin), ub - margin)


def _count_near_bounds(v: Mat, lb: Vec, ub: Vec) -> int:
    width = ub - lb
    tol = np.where(np.isfinite(width), width * 1.0e-2, 0.0)
    return int(np.sum((v - lb < tol) | (ub - v < tol)))


def _barrier_terms(v: Mat, lb: Mat, ub: Mat) -> tuple[Mat, Mat]:
    """Gradient and sqrt-Hessian of phi(v) = -log(ub - v) - log(v - lb) (Wan2018 eqs. 44, 46b).

    Infinite bounds contribute nothing (1/inf = 0).
    """
    with np.errstate(divide="ignore"):
        iu = 1.0 / (ub - v)
        il = 1.0 / (v - lb)
    return iu - il, np.sqrt(iu * iu + il * il)


def barrier_ip_qp(
    n: int,
    p_diag: Vec,
    q_diag: Vec,
    r_diag: Vec,
    a: Mat,
    b: Mat,
    cm: Mat,
    f: Mat,
    ry: Mat,
    ru: Mat,
    dxl: Mat,
    dxu: Mat,
    dul: Mat,
    duu: Mat,
    ip: IpSettings,
) -> tuple[Mat, Mat, Vec]:
    """Infeasible-start primal barrier IP for the QP (42) (Wan2018 Algorithm 1).

    Parameters
    ----------
    n : number of nodes in use (arrays may be longer)
    a, b : (>= n-1, n_x, n_x), (>= n-1, n_x, n_u) A_i, B_i
    cm : (>= n, n_y, n_x) C_i with zeroed rows for lost outputs
    f : (>= n-1, n_x) defects f_i; ry : (>= n, n_y) r_y,i; ru : (>= n-1, n_u) r_u,i
    dxl, dxu, dul, duu : bounds on Delta x_i, Delta u_i (+-inf where unbounded)

    Returns
    -------
    dx (like ry rows, n_x), du, step sizes s_j
    """
    n_x, n_u = a.shape[1], b.shape[2]
    n_y = cm.shape[1]
    dx = np.zeros((cm.shape[0], n_x))
    du = np.zeros((max(cm.shape[0] - 1, 0), n_u))
    q_inv = 1.0 / q_diag
    n_iter = ip.n_kappa * ip.n_qp
    steps = np.zeros(n_iter)
    kappa = ip.kappa_init
    cbar = np.zeros((n, n_y + n_x, n_x))
    rbar_diag = np.ones(n_y + n_x)
    rbar_diag[:n_y] = r_diag
    rybar = np.zeros((n, n_y + n_x))
    qbar = np.zeros((max(n - 1, 0), n_u))
    rubar = np.zeros((max(n - 1, 0), n_u))
    rp = np.zeros((max(n - 1, 0), n_x))
    m = n_y + n_x if ip.constrained else n_y  # rows of C_bar (46e); barrier rows only if used
    for j in range(n_iter):
        # Linearisation (46)
        for i in range(n):
            cbar[i, :n_y] = cm[i]
            rybar[i, :n_y] = ry[i] - cm[i] @ dx[i]
            if ip.constrained:
                g, lsq = _barrier_terms(dx[i], dxl[i], dxu[i])
                sk = np.sqrt(kappa)
                cbar[i, n_y:] = np.diag(sk * lsq)
                with np.errstate(divide="ignore", invalid="ignore"):
                    rybar[i, n_y:] = np.where(lsq > 0.0, -sk * g / lsq, 0.0)
            if i < n - 1:
                if ip.constrained:
                    gu, lu = _barrier_terms(du[i], dul[i], duu[i])
                else:
                    gu, lu = np.zeros(n_u), np.zeros(n_u)
                qbar[i] = 1.0 / (q_inv + kappa * lu * lu)
                rubar[i] = qbar[i] * (q_inv * (ru[i] - du[i]) - kappa * gu)
                rp[i] = -f[i] - a[i] @ dx[i] - b[i] @ du[i] + dx[i + 1]
        d2x, d2u = riccati_direction(
            n, p_diag, a, b, cbar[:, :m], rbar_diag[:m], qbar, -dx[0], rubar, rybar[:, :m], rp
        )
        # Backtracking line search: largest 2^-ns keeping every iterate strictly inside.
        s = 0.0
        if ip.constrained:
            for ns in range(ip.n_s_max + 1):
                t = 2.0**-ns
                ex = dx[:n] + t * d2x
                eu = du[: n - 1] + t * d2u
                if (
                    np.all(ex > dxl[:n])
                    and np.all(ex < dxu[:n])
                    and np.all(eu > dul[: n - 1])
                    and np.all(eu < duu[: n - 1])
                ):
                    s = t
                    break
        else:
            s = 1.0
        steps[j] = s
        dx[:n] += s * d2x
        if n > 1:
            du[: n - 1] += s * d2u
        # n_kappa values of kappa, n_QP iterations each (see module docstring).
        if (j + 1) % ip.n_qp == 0:
            kappa *= ip.kappa_factor
    return dx, du, steps


def riccati_direction(
    n: int,
    p_diag: Vec,
    a: Mat,
    b: Mat,
    cbar: Mat,
    rbar_diag: Vec,
    qbar_diag: Mat,
    rx: Vec,
    rubar: Mat,
    rybar: Mat,
    rp: Mat,
) -> tuple[Mat, Mat]:
    """Search direction of the equality-constrained linear MHE (45) (Wan2018 Algorithm 2).

    Minimises ``1/2|rx - d_l|^2_{P^-1} + 1/2 sum |rubar_i - e_i|^2_{Qbar_i^-1}
    + 1/2 sum |rybar_i - Cbar_i d_i|^2_{Rbar^-1}`` subject to
    ``d_{i+1} = -rp_i + A_i d_i + B_i e_i``, by a Kalman-filter factorisation (lines 1-9),
    forward recursion (10-18) and backward (Bryson-Frazier) recursion (19-27).
    ``rubar_i`` is the minimiser of the input term (see the module docstring on eq. 46d).

    Returns
    -------
    d : (n, n_x) Delta^2 x_i;  e : (n-1, n_u) Delta^2 u_i
    """
    n_x = a.shape[1] if a.shape[0] else p_diag.size
    pi_ = np.empty((n, cbar.shape[1], n_x))
    om = np.empty((n, n_x, cbar.shape[1]))
    kg = np.empty((n, n_x, cbar.shape[1]))
    pf = np.empty((n, n_x, n_x))
    p_hat = np.diag(p_diag)
    for i in range(n):
        c_i = cbar[i]
        pi_[i] = c_i @ p_hat
        s_mat = pi_[i] @ c_i.T
        s_mat[np.diag_indices_from(s_mat)] += rbar_diag
        xi = np.linalg.inv(s_mat)
        om[i] = c_i.T @ xi
        kg[i] = p_hat @ om[i]
        pf[i] = p_hat - kg[i] @ pi_[i]
        if i < n - 1:
            bq = b[i] * qbar_diag[i]
            p_hat = a[i] @ pf[i] @ a[i].T + bq @ b[i].T
    # forward recursion
    xp = np.empty((n, n_x))
    rr = np.empty((n, cbar.shape[1]))
    x_hat = rx
    for i in range(n):
        rr[i] = rybar[i] - cbar[i] @ x_hat
        xp[i] = x_hat + kg[i] @ rr[i]
        if i < n - 1:
            x_hat = -rp[i] + a[i] @ xp[i] + b[i] @ rubar[i]
    # backward recursion
    d = np.empty((n, n_x))
    e = np.empty((max(n - 1, 0), b.shape[2]))
    d[n - 1] = xp[n - 1]
    lam = -om[n - 1] @ rr[n - 1]
    for i in range(n - 2, -1, -1):
        xi_v = a[i].T @ lam
        e[i] = rubar[i] - qbar_diag[i] * (b[i].T @ lam)
        d[i] = xp[i] - pf[i] @ xi_v
        if i > 0:
            lam = xi_v - om[i] @ (rr[i] + pi_[i] @ xi_v)
    return d, e


# --------------------------------------------------------------------------------------------
# Compiled path (numba, filters/_mhe_jit.py), imported lazily so that importing this module stays
# cheap. The numpy functions above are the reference; tests/gcs_monitor/filters/test_mhe.py checks
# that both agree to round-off.


class _Kernels(Protocol):
    def shift(self, *args: object) -> int: ...

    def ip_solve(self, *args: object) -> bool: ...

    def rti_solve(self, *args: object) -> tuple[bool, int]: ...


def compiled_kernel() -> _Kernels | None:
    """The numba kernels module (``filters/_mhe_jit.py``), or None when numba is not installed."""
    return optional_module("gcs_monitor.filters._mhe_jit")


def _step_compiled(
    kern: _Kernels,
    s: MheState,
    model: MheModel,
    y: Vec,
    y_mask: Vec,
    theta_p: Vec,
    dt_s: float,
    weights: MheWeights,
    bounds: MheBounds,
    ip: IpSettings,
) -> tuple[MheState, MheInfo]:
    """:func:`_step_reference` through the kernels: shift, model linearisation, QP, result."""
    big_n = s.x.shape[0]
    n_x, n_u, n_y = model.n_x, model.n_u, model.n_y
    # x_hat_{k|k-1} = F(x_hat_{k-1|k-1}, 0, Theta_{k-1}), appended by the shift
    x_node = model.f(s.x[s.n - 1], np.zeros(n_u), s.theta[s.n - 1], dt_s)
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
