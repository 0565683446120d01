"""Numba kernel of the recursive third-order Levant differentiator (Atmaca2025 eqs. 47-50).

The implementation ``sliding_mode.hosm_step`` runs (loaded through
``gcs_monitor.core.kernels.load_kernels``); the numpy reference of the equivalence test is
``tests/reference/sliding_mode.py``. The exponents and the recursive form are explained in the
``sliding_mode`` module docstring.
"""
# ruff: noqa: N803
# mypy: disable-error-code="no-untyped-def"

from __future__ import annotations

import math

import numba
import numpy as np

jit = numba.njit(cache=True, fastmath=False, nogil=True)


@jit
def hosm_step(z, f, lambdas, dt_s, z_next):
    """One explicit-Euler step of eqs. 47-50; ``z`` (4, nch) at t_k, writes ``z_next`` (4, nch)
    at t_{k+1}."""
    for c in range(f.shape[0]):
        z0, z1, z2, z3 = z[0, c], z[1, c], z[2, c], z[3, c]
        e0 = z0 - f[c]
        v0 = -lambdas[0, c] * abs(e0) ** 0.75 * np.sign(e0) + z1
        e1 = z1 - v0
        v1 = -lambdas[1, c] * abs(e1) ** (2.0 / 3.0) * np.sign(e1) + z2
        e2 = z2 - v1
        v2 = -lambdas[2, c] * math.sqrt(abs(e2)) * np.sign(e2) + z3
        v3 = -lambdas[3, c] * np.sign(z3 - v2)
        z_next[0, c] = z0 + v0 * dt_s
        z_next[1, c] = z1 + v1 * dt_s
        z_next[2, c] = z2 + v2 * dt_s
        z_next[3, c] = z3 + v3 * dt_s
