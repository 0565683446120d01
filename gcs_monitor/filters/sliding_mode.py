"""Levant higher-order sliding-mode (HOSM) differentiator, third order (Atmaca2025 eqs. 47-50).

Atmaca2025 writes the differentiator "in discrete and nonrecursive form" but prints the exponents
3/4, 2/3, 1/2, 0 of Levant's *recursive* form (Levant 1998/2003); in the nonrecursive form the
exponents would be 3/4, 2/4, 1/4, 0 and every layer would be driven by ``z0 - f``. Eqs. 48-50
also print ``z_j - mu_hat`` as the sliding variable of every layer, which is dimensionally wrong
(``z_1`` is a derivative of ``mu_hat``). We implement the recursive Levant differentiator whose
exponents the paper prints, with each layer driven by the output of the layer above:

    v0 = -lambda0 |z0 - f|^{3/4}  sign(z0 - f)  + z1        (eq. 47)
    v1 = -lambda1 |z1 - v0|^{2/3} sign(z1 - v0) + z2        (eq. 48)
    v2 = -lambda2 |z2 - v1|^{1/2} sign(z2 - v1) + z3        (eq. 49)
    z3' = -lambda3 sign(z3 - v2)                             (eq. 50)

discretised, as the paper does, by explicit Euler: ``z_j(t_{k+1}) = z_j(t_k) + v_j(t_k) dt``.
Caveat of explicit Euler: the accuracy of ``z_j`` is ``O(L dt^{n+1-j})`` in the noise-free case,
and the chattering amplitude grows with ``lambda dt``; Levant's discrete differentiators add
Taylor terms ``z_{j+2} dt^2 / 2 ...`` that the paper does not use.

The paper gives no values for ``lambda_{0..3}`` ("trial and error"). Following Levant (2003) they
are ``lambda_j = k_j L^{1/(n+1-j)}`` with Levant's coefficients ``k = (3, 2, 1.5, 1.1)`` for n = 3
and ``L`` an upper bound of ``|f^{(4)}|``, one per channel.

The step runs in the numba kernel of ``filters/_sliding_mode_jit.py``; the numpy reference that
the equivalence test compares it with is ``tests/reference/sliding_mode.py``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gcs_monitor.core.kernels import load_kernels
from gcs_monitor.core.types import Mat, Vec

HOSM_ORDER = 3


@dataclass(frozen=True, slots=True)
class LevantGains:
    """Recursive Levant coefficients for n = 3 (Levant 2003, Int. J. Control 76, Sec. 4).

    Attributes
    ----------
    k : (k0, k1, k2, k3) dimensionless coefficients of layers 0..3
    """

    k: tuple[float, float, float, float] = (3.0, 2.0, 1.5, 1.1)

    def lambdas(self, lipschitz: Vec) -> Mat:
        """Paper gains ``lambda_j = k_j L^{1/(n+1-j)}`` (eqs. 47-50), shape (4, n_channels)."""
        L = np.asarray(lipschitz, dtype=np.float64)
        n = HOSM_ORDER
        return np.stack([self.k[j] * L ** (1.0 / (n + 1 - j)) for j in range(n + 1)])


@dataclass(frozen=True, slots=True)
class HosmState:
    """Differentiator state: ``z[j]`` estimates the j-th derivative of the input, shape (4, nch)."""

    z: Mat


def hosm_init(f0: Vec) -> HosmState:
    """Start at the first sample with zero derivatives."""
    z = np.zeros((HOSM_ORDER + 1, np.asarray(f0).shape[0]))
    z[0] = f0
    return HosmState(z=z)


def hosm_step(s: HosmState, f: Vec, lambdas: Mat, dt_s: float) -> HosmState:
    """One explicit-Euler step of the recursive third-order differentiator (eqs. 47-50).

    Parameters
    ----------
    s : state at t_k
    f : (nch,) sample of the differentiated signal at t_k (``mu_hat`` in the paper)
    lambdas : (4, nch) gains from :meth:`LevantGains.lambdas`
    dt_s : step (s)

    Returns
    -------
    state at t_{k+1}; ``z[1]`` is the derivative estimate (eq. 51)
    """
    kern = load_kernels("gcs_monitor.filters._sliding_mode_jit")
    z_next = np.empty_like(s.z)
    kern.hosm_step(s.z, np.asarray(f, dtype=np.float64), lambdas, float(dt_s), z_next)
    return HosmState(z=z_next)
