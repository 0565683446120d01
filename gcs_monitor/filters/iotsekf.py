"""IOTSEKF step on a caller's discretisation, for input faults (Lu2017 sec. IV.B, eqs. 14-36).

Lu2017's IOTSEKF is the iterated optimal two-stage EKF of Lu2016 (Hsieh & Chen 1999):
a bias-free filter, a bias (fault) filter, the coupling and the blend. This module runs it when
the caller supplies the discretisation -- the transition ``Phi`` (eq. 19), the fault input
matrix ``Gamma`` (eq. 20), the discrete process noise ``Q_d`` of the *state* and the propagated
bias-free state (eq. 17) -- for models whose input is not a measured signal (the servo's valve
command comes from its own NDI law, so the model is the closed loop), with a linear output
``y = H x`` (Lu2017 eq. 5). The equations are those of ``filters/two_stage.py``: the kernel
``filters/_iotsekf_jit.py`` chains its equation segments. The state dataclass is
:class:`~gcs_monitor.filters.two_stage.TwoStageState` (no adaptation window: ``gamma2`` is
empty; Lu2017 fixes ``Q^{f^i}``).

Choices where the printed text is ambiguous (docs/papers-notes.md, Lu2017):

1. Eq. 19 linearises at ``x_hat_{k-1|k-1}``, eq. 20 evaluates ``G`` at ``x_bar_{k-1|k-1}``; the
   caller linearises both along the blended estimate with the fault estimate held (the
   augmented-state EKF's point, as Lu2016 note 1 in ``two_stage.py``).
2. Eq. 20 prints ``Gamma = int Phi_{k-1} G dtau``; the integrand is ``exp(A t)`` (Lu2016
   note 2).
3. The iteration of eqs. 21-23 changes nothing for a linear output (one pass, see the kernel).
4. ``Q^{xf} = 0`` (Lu2017 gives no cross covariance; as Lu2016).
"""

from __future__ import annotations

import numpy as np

from gcs_monitor.core.kernels import load_kernels
from gcs_monitor.core.types import Mat, Vec
from gcs_monitor.filters.ekf import Innovation
from gcs_monitor.filters.two_stage import TwoStageState

_KERNEL = "gcs_monitor.filters._iotsekf_jit"


def iotsekf_init(x0: Vec, P0: Mat, f0: Vec, Pf0: Mat, Qf: Mat, *, m: int) -> TwoStageState:
    """Initial state, no state/fault cross covariance (``V_0 = 0``)."""
    n, b = len(x0), len(f0)
    x = np.array(x0, dtype=np.float64)
    P = np.array(P0, dtype=np.float64)
    return TwoStageState(x_bar=x.copy(), P_bar=P.copy(), f=np.array(f0, dtype=np.float64),
                         Pf=np.array(Pf0, dtype=np.float64), V=np.zeros((n, b)),
                         Qf=np.array(Qf, dtype=np.float64), x=x, Px=P, k=0,
                         gamma2=np.zeros((0, m)))


def iotsekf_step(s: TwoStageState, x_bar_prop: Vec, Phi: Mat, Gam: Mat, Qd: Mat, H: Mat,
                 y: Vec, R: Mat, *, gate_sigma: float = 3.0
                 ) -> tuple[TwoStageState, Innovation]:
    """One step from k-1 to k (eqs. 14-36).

    Parameters
    ----------
    s : the filter at k-1 (its ``Qf`` is the fault random walk of eq. 14)
    x_bar_prop : (n,) bias-free state propagated with zero fault (eq. 17 without ``u_bar``)
    Phi, Gam, Qd : (n, n), (n, b), (n, n) discretisation over the interval (eqs. 19-20, 18)
    H, y, R : linear output, measurement, its noise covariance

    Returns
    -------
    The filter at k (the input state, unchanged, on a numerical failure) and the bias-filter
    innovation of eq. 27 with its covariance's diagonal (eq. 29).
    """
    n, b, m = Phi.shape[0], Gam.shape[1], y.size
    out = np.empty(n + n * n + b + b * b + n * b + n + n * n)
    inn = np.empty(3 * m)
    code = load_kernels(_KERNEL).step(
        np.asarray(x_bar_prop, dtype=np.float64), np.asarray(Phi, dtype=np.float64),
        np.asarray(Gam, dtype=np.float64), np.asarray(Qd, dtype=np.float64), s.Qf, s.x_bar,
        s.P_bar, s.f, s.Pf, s.V, np.asarray(H, dtype=np.float64),
        np.asarray(y, dtype=np.float64), np.asarray(R, dtype=np.float64), float(gate_sigma),
        out, inn)
    innov = Innovation(nu=inn[:m].copy(), S_diag=inn[m:2 * m].copy(),
                       test_ratio=inn[2 * m:].copy(), numerics_ok=code == 0)
    if code != 0:
        return s, innov
    o = np.cumsum([0, n, n * n, b, b * b, n * b, n, n * n])
    return TwoStageState(
        x_bar=out[o[0]:o[1]], P_bar=out[o[1]:o[2]].reshape(n, n), f=out[o[2]:o[3]],
        Pf=out[o[3]:o[4]].reshape(b, b), V=out[o[4]:o[5]].reshape(n, b), Qf=s.Qf,
        x=out[o[5]:o[6]], Px=out[o[6]:o[7]].reshape(n, n), k=s.k + 1, gamma2=s.gamma2), innov
