"""Numba kernel of one LPV sliding-mode observer step (Chen2020 eqs. 3, 6, 7, 21).

The implementation ``lpv_smo.smo_step`` runs (loaded through
``gcs_monitor.core.kernels.load_kernels``); the numpy reference of the equivalence test is
``tests/reference/lpv_smo.py``. Coordinates and the affine stacks are explained in the
``lpv_smo`` module docstring. Plain loops: the matrices are at most 5 x 12.
"""
# ruff: noqa: N803, N806
# mypy: disable-error-code="no-untyped-def"

from __future__ import annotations

import math

import numba

jit = numba.njit(cache=True, fastmath=False, nogil=True)


@jit
def smo_step(z, z_f, W, Gn, A_f, A_f_inv, perm, k, delta, y_p, u, rho1, rho2, dt,
             z_next, zf_next, f_hat, x_hat, e_y, nu, v):
    """One explicit-Euler step; writes the state at t_{k+1} (``z_next``, ``zf_next``) and the
    outputs at t_k (``f_hat``, ``x_hat``, ``e_y``, ``nu``); ``v`` is scratch of the length of
    ``W``'s rows ([z; u; y; 1])."""
    nz = z.shape[0]
    q = z_f.shape[0]
    n = nz - q
    m = u.shape[0]
    # y = [y_p1; z_f] in the permuted order; e_y = C z - y (eq. 6)
    ne2 = 0.0
    for i in range(n):
        yi = y_p[perm[q + i]] if i < n - q else z_f[i - (n - q)]
        e = z[q + i] - yi
        e_y[i] = e
        ne2 += e * e
        v[nz + m + i] = yi
    g = -k / (math.sqrt(ne2) + delta)  # eq. 7, sigmoid smoothing (Chen2020 sec. V)
    for i in range(n):
        nu[i] = g * e_y[i]
    for i in range(q):  # eq. 21, W = [0 A_f^-1]
        s = 0.0
        for j in range(q):
            s += A_f_inv[i, j] * nu[n - q + j]
        f_hat[i] = s
    for i in range(nz):
        v[i] = z[i]
    for i in range(m):
        v[nz + i] = u[i]
    v[nz + m + n] = 1.0
    ncol = W.shape[2]
    for i in range(nz):
        s = 0.0
        for j in range(ncol):
            s += (W[0, i, j] + rho1 * W[1, i, j] + rho2 * W[2, i, j]) * v[j]
        for j in range(n):
            s += Gn[i, j] * nu[j]
        z_next[i] = z[i] + dt * s
    for i in range(q):  # eq. 3
        s = 0.0
        for j in range(q):
            s += A_f[i, j] * (y_p[perm[j]] - z_f[j])
        zf_next[i] = z_f[i] + dt * s
    for i in range(n):
        x_hat[perm[i]] = z[i]
