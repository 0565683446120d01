"""Numba kernel of the estimator's hot path: one ATSEKF step on the GS-KM (Lu2016) in one call.

``imu_ts.ImuTwoStageEstimator`` after the iterated first steps: the GS-KM Jacobians at the
blended estimate with the fault-corrected input (Lu2016 note 1, eqs. 13, 34), its propagation
(eq. 31) and the packed two-stage step (eqs. 31-58). No equation of its own: it makes the calls
the estimator made one by one (``models/_kinematics_jit.py`` ``jacobians`` and ``propagate``,
then ``filters/_two_stage_jit.py`` ``step_identity_output``), in one dispatch. The same
operations, so the same numbers: tests/gcs_monitor/families/imu/test_imu_ts.py checks the
estimator on this path against the plain ``two_stage_step``, bit for bit. Loaded through
``gcs_monitor.core.kernels``.
"""
# mypy: disable-error-code="no-untyped-def"

from __future__ import annotations

import numba
import numpy as np

from gcs_monitor.filters._two_stage_jit import _unpack, step_identity_output
from gcs_monitor.models._kinematics_jit import jacobians, propagate

# this file calls these files' jitted functions: see gcs_monitor.core.kernels
KERNEL_DEPENDENCIES = {
    "gcs_monitor.filters._two_stage_jit": "793751f1759a3961",
    "gcs_monitor.models._kinematics_jit": "baac8103a24ee2a8",
}

jit = numba.njit(cache=True, fastmath=False, nogil=True)


@jit
def gs_km_step(s_in, k, s_out, u_prev, u_now, lat_rad, alt_m, g_mps2, F, G, xb, y, Q, R,
               adapt, dt, gate, nwin, out):
    """``step_identity_output`` (``PackedTwoStage`` layout, same arguments and return codes)
    with ``F``, ``G`` (eq. 34) and ``xb`` (eq. 31 without u_bar) computed first from the packed
    state ``s_in``: ``jacobians(x, u_prev - f, ...)`` (Lu2016 note 1) and
    ``propagate(x_bar, u_prev, u_now, ...)``; ``F``, ``G``, ``xb`` are work arrays it writes."""
    n = F.shape[0]
    b = G.shape[1]
    m = y.shape[0]
    x_bar, _P_bar, f, _Pf, _V, _Qf, x, _Px, _gamma2 = _unpack(s_in, n, b, m, nwin)
    u_corr = np.empty(b)
    for i in range(b):
        u_corr[i] = u_prev[i] - f[i]  # Lu2016 note 1: the fault-corrected input
    jacobians(x, u_corr, lat_rad, alt_m, F, G)  # eqs. 13, 34
    propagate(x_bar, u_prev, u_now, lat_rad, alt_m, g_mps2, dt, xb)  # eq. 31
    return step_identity_output(s_in, k, s_out, F, G, xb, y, Q, R, adapt, dt, gate, nwin, out)
