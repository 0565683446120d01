"""Numpy reference of the real-time MHE kernels (Wan2018 sec. V, Algorithms 1-2;
``filters/_mhe_jit.py``).

The algorithm and the corrections to the printed equations are those of
``gcs_monitor.filters.mhe`` (module docstring there). Here Algorithm 1 (:func:`barrier_ip_qp`)
and Algorithm 2 (:func:`riccati_direction`) are separate numpy functions, which the tests also
check against a dense KKT solve and a general box-constrained QP solver.
"""

from __future__ import annotations

import numpy as np

from gcs_monitor.core.types import Mat, Vec
from gcs_monitor.filters.mhe import (
    IpSettings,
    MheBounds,
    MheInfo,
    MheModel,
    MheState,
    MheWeights,
    _linearise,
)


def mhe_step_reference(
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
    """:func:`gcs_monitor.filters.mhe.mhe_step` in numpy: the same shift, linearisation through
    the model's methods (:func:`~gcs_monitor.filters.mhe._linearise`), QP and result."""
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
