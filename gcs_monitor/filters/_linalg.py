"""Small dense linear algebra for the filter kernels (numba), written once.

Used by ``_two_stage_jit`` (Lu2016), ``_otsekf_jit`` (Atmaca2025) and ``_mhe_jit`` (Wan2018):

* :func:`cholesky`, :func:`cho_solve`, :func:`cho_solve_right` -- symmetric positive definite
  solves ``S X = B`` and ``X S = M`` (Kalman gains ``K = P H^T S^{-1}``) through ``S = L L^T``;
* :func:`gauss_jordan_inverse` -- inverse of a general square matrix (Lu2016 eq. 57);
* :func:`matmul`, :func:`matmul_t`, :func:`matvec`, :func:`symmetrise`, :func:`joseph` -- loop
  products for the kernels that avoid a BLAS call per 6x6 product.

The matrices are 4x4 to 8x8: a LAPACK call costs more than the arithmetic, and numba's LAPACK
wrappers raise on a matrix that is not positive definite, where a filter must report
``numerics_ok = False`` instead. Every function writes into arrays the caller passes in and
returns an ok flag where a factorisation can fail; only :func:`gauss_jordan_inverse`
allocates (its work copy of ``A``).

The operation order is part of the interface: the replays of the fixed flights are recorded
bit for bit, so a change here changes the monitor's output. Kernel modules that call these
functions list this file's digest in ``KERNEL_DEPENDENCIES`` (see ``gcs_monitor.core.kernels``).
"""
# ruff: noqa: N803, N806, E741
# mypy: disable-error-code="no-untyped-def"

from __future__ import annotations

import math

import numba

jit = numba.njit(cache=True, fastmath=False, nogil=True)


@jit
def cholesky(A, L):
    """Lower Cholesky factor of the symmetric ``A`` (n, n) into ``L``; False if ``A`` is not PD.

    Reads only the lower triangle of ``A``; ``L`` may be ``A`` itself (factorised in place).
    The strict upper triangle of ``L`` is set to zero. Non-finite input gives False (the
    pivot test ``d > 0`` fails on NaN). On False, ``L`` holds a partial factor.
    """
    n = A.shape[0]
    for i in range(n):
        for j in range(i + 1, n):
            L[i, j] = 0.0
    for j in range(n):
        d = A[j, j]
        for k in range(j):
            d -= L[j, k] * L[j, k]
        if not d > 0.0:  # also catches NaN
            return False
        ljj = math.sqrt(d)
        L[j, j] = ljj
        for i in range(j + 1, n):
            v = A[i, j]
            for k in range(j):
                v -= L[i, k] * L[j, k]
            L[i, j] = v / ljj
    return True


@jit
def cho_solve(L, X):
    """Overwrite ``X`` (n, r) with ``(L L^T)^{-1} X``, column by column (forward, then back)."""
    n, r = X.shape
    for c in range(r):
        for i in range(n):
            v = X[i, c]
            for k in range(i):
                v -= L[i, k] * X[k, c]
            X[i, c] = v / L[i, i]
        for i in range(n - 1, -1, -1):
            v = X[i, c]
            for k in range(i + 1, n):
                v -= L[k, i] * X[k, c]
            X[i, c] = v / L[i, i]


@jit
def cho_solve_right(L, M, out):
    """``out = M (L L^T)^{-1}`` for ``M`` (r, n): the gain form ``K = P H^T S^{-1}``.

    Row ``c`` of ``out`` is :func:`cho_solve` of row ``c`` of ``M`` (``S`` symmetric), so both
    make the same operations. ``out`` must not be ``M``.
    """
    out[:, :] = M
    cho_solve(L, out.T)


@jit
def gauss_jordan_inverse(A, X):
    """``X = A^{-1}`` by Gauss-Jordan elimination with partial pivoting; False if singular.

    ``A`` is not modified. On False, ``X`` is undefined.
    """
    n = A.shape[0]
    M = A.copy()
    for i in range(n):
        for j in range(n):
            X[i, j] = 1.0 if i == j else 0.0
    for c in range(n):
        p = c
        for i in range(c + 1, n):
            if abs(M[i, c]) > abs(M[p, c]):
                p = i
        if M[p, c] == 0.0:
            return False
        if p != c:
            for j in range(n):
                M[c, j], M[p, j] = M[p, j], M[c, j]
                X[c, j], X[p, j] = X[p, j], X[c, j]
        piv = M[c, c]
        for j in range(n):
            M[c, j] /= piv
            X[c, j] /= piv
        for i in range(n):
            if i != c:
                fct = M[i, c]
                if fct != 0.0:
                    for j in range(n):
                        M[i, j] -= fct * M[c, j]
                        X[i, j] -= fct * X[c, j]
    return True


@jit
def matmul(A, B, out):
    """``out = A @ B`` by loops, each entry summed over ``t`` in ascending order."""
    n, k = A.shape
    m = B.shape[1]
    for i in range(n):
        for j in range(m):
            acc = 0.0
            for t in range(k):
                acc += A[i, t] * B[t, j]
            out[i, j] = acc


@jit
def matmul_t(A, B, out):
    """``out = A @ B.T`` by loops (as :func:`matmul`)."""
    n, k = A.shape
    m = B.shape[0]
    for i in range(n):
        for j in range(m):
            acc = 0.0
            for t in range(k):
                acc += A[i, t] * B[j, t]
            out[i, j] = acc


@jit
def matvec(A, x, out):
    """``out = A @ x`` by loops (as :func:`matmul`)."""
    n, k = A.shape
    for i in range(n):
        acc = 0.0
        for t in range(k):
            acc += A[i, t] * x[t]
        out[i] = acc


@jit
def symmetrise(P):
    """``P = (P + P^T) / 2`` in place."""
    n = P.shape[0]
    for i in range(n):
        for j in range(i + 1, n):
            v = (P[i, j] + P[j, i]) * 0.5
            P[i, j] = v
            P[j, i] = v


@jit
def joseph(P, K, H, R, out, A, T1, T2, KR):
    """Joseph-form update ``out = (I - K H) P (I - K H)^T + K R K^T``, symmetrised.

    Stays PSD for any gain (Lu2016 eq. 39, Atmaca2025 eqs. 24, 34). ``A``, ``T1``, ``T2``
    (n, n) and ``KR`` (n, m) are work arrays.
    """
    n = P.shape[0]
    matmul(K, H, A)
    for i in range(n):
        for j in range(n):
            A[i, j] = -A[i, j]
        A[i, i] += 1.0
    matmul(A, P, T1)
    matmul_t(T1, A, T2)
    matmul(K, R, KR)
    matmul_t(KR, K, out)
    for i in range(n):
        for j in range(n):
            out[i, j] += T2[i, j]
    symmetrise(out)
