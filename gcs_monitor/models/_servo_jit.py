"""The monitor's closed-loop servo model in numba (Lu2017 eqs. 4-13): its one implementation.

The servo as a ground monitor sees it: the hydraulic plant (eq. 4) driven by the NDI valve law
(eq. 13, relative degree 3, see ``models/servo.py``) on the model's own states, tracking the
third-order reference model driven by the rod command, with the input fault ``f^i`` added to
the saturated valve command (as the simulator's servo adds an OFC). State
``s = [x1, x2, x3, r, r', r'']``. The reference states are internal to the servo electronics:
the IOTSEKF estimates them with the plant states; the RTS-EKF's nominal servo carries them.

* :func:`deriv` -- ``ds/dt``;
* :func:`jacobian` -- ``A = ds_dot/ds`` (6, 6) of the *closed* loop (the NDI law depends on
  the plant and the reference states) and ``G = ds_dot/df^i`` (6,);
* :func:`propagate` -- RK4 over one sample interval in substeps, the rod command piecewise
  linear between its two samples, with the transition ``Phi`` and the fault input matrix
  ``Gamma`` as the tangent of the RK4 map (the variational equation integrated with the same
  stages) and the discrete process noise ``Q_d`` accumulated over the substeps;
* :func:`command_timing_noise` -- the state uncertainty of a command change at an unknown
  instant inside the interval.

The chamber gain ``c(x1)`` is evaluated with x1 clamped to the rod stroke (it is singular at
``x1 = V_m / A_p``, far outside the stroke). The constants travel in one array built by
``models.servo.pack_params`` (``P_*`` indices). The plain-float reference of the equivalence
test is ``tests/reference/servo_model.py``. Loaded through ``gcs_monitor.core.kernels``.
"""
# ruff: noqa: N803, N806, E741
# mypy: disable-error-code="no-untyped-def"

from __future__ import annotations

import math

import numba
import numpy as np

jit = numba.njit(cache=True, fastmath=False, nogil=True)

(
    P_APS, P_BB, P_INV_M, P_VMAX, P_LEAK, P_CNUM, P_VM2, P_A2, P_W3, P_Z2W2, P_Z2W,
    P_K2, P_K1, P_K0, P_UMAX, P_STROKE,
) = range(16)
N_PARAMS = 16
N_S = 6  # [x1, x2, x3, r, r', r'']
N_X = 3  # plant states the filters estimate
SQRT_FLOOR = 1.0e-6  # floor under sqrt(1 - sign x3) in the NDI law, as the simulator's servo


@jit
def chamber(x1, prm):
    """``(c(x1), dc/dx1)``: the chamber gain of eq. 4 row 3, x1 clamped to the stroke."""
    st = prm[P_STROKE]
    inside = True
    if x1 > st:
        x1 = st
        inside = False
    elif x1 < -st:
        x1 = -st
        inside = False
    den = prm[P_VM2] - prm[P_A2] * x1 * x1
    c = prm[P_CNUM] / den
    dc = c * 2.0 * prm[P_A2] * x1 / den if inside else 0.0
    return c, dc


@jit
def reference_jerk(s, q_com, prm):
    """``r'''`` of the reference model ``w^3 / ((s + w)(s^2 + 2 zeta w s + w^2))``."""
    return prm[P_W3] * (q_com - s[3]) - prm[P_Z2W2] * s[4] - prm[P_Z2W] * s[5]


@jit
def _ndi(s, q_com, prm):
    """The NDI law of :func:`ndi` without allocations: ``(u, du/dx1, du/dx2, du/dx3,
    1/(L_g L_f^2 h), saturated)``."""
    x1 = s[0]
    x2 = s[1]
    x3 = s[2]
    aps = prm[P_APS]
    bb = prm[P_BB]
    inv_m = prm[P_INV_M]
    leak = prm[P_LEAK]
    k2 = prm[P_K2]
    k1 = prm[P_K1]
    k0 = prm[P_K0]
    rddd = reference_jerk(s, q_com, prm)
    cy, dcy = chamber(x1, prm)
    ydd = (aps * x3 - bb * x2) * inv_m
    lf3h = (aps * cy * (-leak * x3 - x2) - bb * ydd) * inv_m
    num = rddd + k2 * (s[5] - ydd) + k1 * (s[4] - x2) + k0 * (s[3] - x1) - lf3h
    sg = 1.0 if num >= 0.0 else -1.0
    arg = 1.0 - sg * x3
    floor = arg <= SQRT_FLOOR
    sq = math.sqrt(SQRT_FLOOR if floor else arg)
    b = aps * inv_m * cy * prm[P_VMAX] * sq
    u = num / b
    umax = prm[P_UMAX]
    if u > umax or u < -umax:
        return (umax if u > 0.0 else -umax), 0.0, 0.0, 0.0, 1.0 / b, True
    dydd1 = -bb * inv_m
    dydd2 = aps * inv_m
    dlf0 = aps * dcy * (-leak * x3 - x2) * inv_m
    dlf1 = (-aps * cy - bb * dydd1) * inv_m
    dlf2 = (-aps * cy * leak - bb * dydd2) * inv_m
    db0 = b * dcy / cy
    db2 = 0.0 if floor else -b * sg / (2.0 * arg)
    return (u, (-k0 - dlf0 - u * db0) / b, (-k1 - k2 * dydd1 - dlf1) / b,
            (-k2 * dydd2 - dlf2 - u * db2) / b, 1.0 / b, False)


@jit
def ndi(s, q_com, prm, grad):
    """Saturated NDI valve command (Lu2017 eq. 13, r = 3) and, in ``grad`` (3,), its gradient
    with respect to (x1, x2, x3) (zero when saturated)."""
    u, g0, g1, g2, _ib, _sat = _ndi(s, q_com, prm)
    grad[0] = g0
    grad[1] = g1
    grad[2] = g2
    return u


@jit
def params_tuple(prm):
    """The ``P_*`` constants of ``prm`` (N_PARAMS,) as a tuple: the RK4 stages pass tuples of
    floats, not arrays (a call passing an array costs an atomic reference-count increment and
    decrement, more than the arithmetic of a stage)."""
    return (prm[0], prm[1], prm[2], prm[3], prm[4], prm[5], prm[6], prm[7], prm[8], prm[9],
            prm[10], prm[11], prm[12], prm[13], prm[14], prm[15])


@jit
def _state_tuple(s):
    return (s[0], s[1], s[2], s[3], s[4], s[5])


@jit
def _deriv(s, q_com, f_in, p):
    """:func:`deriv` on tuples: ``s`` (6,) and the constants ``p`` (:func:`params_tuple`);
    returns ``ds/dt`` as a tuple."""
    u, _g0, _g1, _g2, _ib, _sat = _ndi(s, q_com, p)
    ut = u + f_in
    sg = 1.0 if ut >= 0.0 else -1.0
    arg = 1.0 - sg * s[2]
    flow = p[P_VMAX] * (math.sqrt(arg) if arg > 0.0 else 0.0) * ut
    cx, _dc = chamber(s[0], p)
    return (s[1], (p[P_APS] * s[2] - p[P_BB] * s[1]) * p[P_INV_M],
            cx * (flow - p[P_LEAK] * s[2] - s[1]), s[4], s[5], reference_jerk(s, q_com, p))


@jit
def deriv(s, q_com, f_in, prm, d):
    """``d = ds/dt`` (6,) of the closed loop with input fault ``f_in`` (valve units)."""
    r = _deriv(_state_tuple(s), q_com, f_in, params_tuple(prm))
    for i in range(N_S):
        d[i] = r[i]


@jit
def jacobian(s, q_com, f_in, prm, A, G):
    """``A = ds_dot/ds`` (6, 6) of the closed loop (the NDI law depends on the plant states x and
    on the reference states r) and ``G = ds_dot/df^i`` (6,) at ``s``.

    The blocks: ``A[:3, :3]`` the plant with the NDI feedback, ``A[:3, 3:]`` the NDI law's
    dependence on the reference states (its feed-forward ``r'''`` included), ``A[3:, 3:]`` the
    reference model, ``A[3:, :3] = 0``.
    """
    u, g0, g1, g2, inv_b, sat = _ndi(s, q_com, prm)
    ut = u + f_in
    sg = 1.0 if ut >= 0.0 else -1.0
    x2 = s[1]
    x3 = s[2]
    arg = 1.0 - sg * x3
    sq = math.sqrt(arg) if arg > 0.0 else 0.0
    dsq = -sg / (2.0 * sq) if sq > 0.0 else 0.0
    cx, dcx = chamber(s[0], prm)
    vmax = prm[P_VMAX]
    leak = prm[P_LEAK]
    for i in range(6):
        for j in range(6):
            A[i, j] = 0.0
        G[i] = 0.0
    A[0, 1] = 1.0
    A[1, 1] = -prm[P_BB] * prm[P_INV_M]
    A[1, 2] = prm[P_APS] * prm[P_INV_M]
    A[2, 0] = dcx * (vmax * sq * ut - leak * x3 - x2) + cx * vmax * sq * g0
    A[2, 1] = cx * (vmax * sq * g1 - 1.0)
    A[2, 2] = cx * (vmax * (dsq * ut + sq * g2) - leak)
    if not sat:  # unsaturated: u depends on r
        # d num / d(r, r', r'') with r''' = w^3 (q - r) - z2 w^2 r' - z2 w r'' fed forward
        k = cx * vmax * sq * inv_b
        A[2, 3] = k * (prm[P_K0] - prm[P_W3])
        A[2, 4] = k * (prm[P_K1] - prm[P_Z2W2])
        A[2, 5] = k * (prm[P_K2] - prm[P_Z2W])
    A[3, 4] = 1.0
    A[4, 5] = 1.0
    A[5, 3] = -prm[P_W3]
    A[5, 4] = -prm[P_Z2W2]
    A[5, 5] = -prm[P_Z2W]
    G[2] = cx * vmax * sq


@jit
def _axpy(x, a, k):
    """``x + a k`` per element of two 6-tuples (``x[i] + a * k[i]``)."""
    return (x[0] + a * k[0], x[1] + a * k[1], x[2] + a * k[2], x[3] + a * k[3],
            x[4] + a * k[4], x[5] + a * k[5])


@jit
def _rk4_sum(k1, k2, k3, k4):
    """``k1 + 2 (k2 + k3) + k4`` per element (RK4's weighted slope, times h / 6)."""
    return (k1[0] + 2.0 * (k2[0] + k3[0]) + k4[0], k1[1] + 2.0 * (k2[1] + k3[1]) + k4[1],
            k1[2] + 2.0 * (k2[2] + k3[2]) + k4[2], k1[3] + 2.0 * (k2[3] + k3[3]) + k4[3],
            k1[4] + 2.0 * (k2[4] + k3[4]) + k4[4], k1[5] + 2.0 * (k2[5] + k3[5]) + k4[5])


@jit
def _rk4(s, qa, qm, qb, f_in, h, p):
    """One RK4 step of :func:`deriv` from the state tuple ``s`` (command qa, qm, qb at 0, h/2,
    h); returns the new state tuple."""
    k1 = _deriv(s, qa, f_in, p)
    k2 = _deriv(_axpy(s, 0.5 * h, k1), qm, f_in, p)
    k3 = _deriv(_axpy(s, 0.5 * h, k2), qm, f_in, p)
    k4 = _deriv(_axpy(s, h, k3), qb, f_in, p)
    return _axpy(s, h / 6.0, _rk4_sum(k1, k2, k3, k4))


@jit
def command_at(qc0, qc1, t, t_knee):
    """The rod command ``t`` into an interval: linear from ``qc0`` to ``qc1`` until ``t_knee``,
    ``qc1`` after it (a reported command took effect before its sample instant)."""
    if t >= t_knee:
        return qc1
    return qc0 + (qc1 - qc0) * t / t_knee


@jit
def _stage_tangent(s, q, f_in, prm, M, A, G, K):
    """``K = A(s) M + [0 | G(s)]`` (6, 7): the variational equation of the closed loop for the
    tangent ``M = [d s / d s_0 | d s / d f^i]`` (``s``, ``prm``: arrays or tuples).

    The product runs over the entries of ``A`` that :func:`jacobian` can make nonzero (rows 0,
    1, 3 and 4 have one or two, row 5 the reference block, row 2 all six), each sum from +0.0
    in ascending column order: a skipped term is an exact zero, which leaves such a sum as it
    was, so ``K`` is the dense product's, bit for bit, for a finite ``M``."""
    jacobian(s, q, f_in, prm, A, G)
    a01 = A[0, 1]
    a11 = A[1, 1]
    a12 = A[1, 2]
    a20 = A[2, 0]
    a21 = A[2, 1]
    a22 = A[2, 2]
    a23 = A[2, 3]
    a24 = A[2, 4]
    a25 = A[2, 5]
    a34 = A[3, 4]
    a45 = A[4, 5]
    a53 = A[5, 3]
    a54 = A[5, 4]
    a55 = A[5, 5]
    for j in range(N_S + 1):
        m0 = M[0, j]
        m1 = M[1, j]
        m2 = M[2, j]
        m3 = M[3, j]
        m4 = M[4, j]
        m5 = M[5, j]
        K[0, j] = 0.0 + a01 * m1
        K[1, j] = 0.0 + a11 * m1 + a12 * m2
        K[2, j] = 0.0 + a20 * m0 + a21 * m1 + a22 * m2 + a23 * m3 + a24 * m4 + a25 * m5
        K[3, j] = 0.0 + a34 * m4
        K[4, j] = 0.0 + a45 * m5
        K[5, j] = 0.0 + a53 * m3 + a54 * m4 + a55 * m5
    for i in range(N_S):
        K[i, N_S] += G[i]


@jit
def propagate(s, qc0, qc1, f_in, dt, t_knee, n_sub, prm, jac, q_valve, q_state, Phi, Gam,
              Qd):
    """RK4 of the closed loop over ``dt`` in ``n_sub`` substeps, in place on ``s`` (6,).

    The rod command runs linearly from ``qc0`` to ``qc1`` until ``t_knee`` into the interval
    and is held at ``qc1`` after it (``t_knee = dt``: linear over the whole interval; see
    :func:`command_at`); ``f_in`` is held.

    With ``jac`` set, also the transition ``Phi`` (6, 6) (Lu2017 eq. 19) and the fault input
    matrix ``Gamma`` (6,) (eq. 20) as the derivatives of the integrated state with respect to
    the initial state and to ``f_in``: the variational equation ``M' = A M + [0 | G]`` rides
    along each RK4 substep with the same stages (the tangent of the discrete RK4 map, exact up
    to the kinks of saturation and sign(u); Lu2017 eqs. 19-20 take ``exp(A dt)`` at the
    interval's start). The discrete process noise (eq. 39, ``Q_k^d``) accumulates per substep
    ``Q_d <- Phi_i Q_d Phi_i^T + (G q_valve G^T + diag(q_state)) h`` (symmetrised) for a
    valve-command noise of PSD ``q_valve`` and state noises of PSDs ``q_state`` (6,). ``A`` is
    block upper triangular, so the plant block ``[:3, :3]`` is the transition of the plant
    states alone with the reference states given.
    """
    h = dt / n_sub
    p = params_tuple(prm)
    x = _state_tuple(s)  # the state as a tuple along the substeps (see params_tuple)
    if not jac:  # the state alone (the filters call this most): no tangent arrays
        for k in range(n_sub):
            t0 = k * h
            qa = command_at(qc0, qc1, t0, t_knee)
            qm = command_at(qc0, qc1, t0 + 0.5 * h, t_knee)
            qb = command_at(qc0, qc1, t0 + h, t_knee)
            x = _rk4(x, qa, qm, qb, f_in, h, p)
        for i in range(N_S):
            s[i] = x[i]
        return
    A = np.empty((N_S, N_S))
    G = np.empty(N_S)
    M = np.empty((N_S, N_S + 1))
    Mt = np.empty((N_S, N_S + 1))
    K1 = np.empty((N_S, N_S + 1))
    K2 = np.empty((N_S, N_S + 1))
    K3 = np.empty((N_S, N_S + 1))
    K4 = np.empty((N_S, N_S + 1))
    W = np.empty((N_S, N_S))
    W2 = np.empty((N_S, N_S))
    g0 = np.empty(N_S)
    gk = np.empty(N_S)
    for i in range(N_S):
        Gam[i] = 0.0
        for j in range(N_S):
            Phi[i, j] = 1.0 if i == j else 0.0
            Qd[i, j] = 0.0
    for k in range(n_sub):
        t0 = k * h
        qa = command_at(qc0, qc1, t0, t_knee)
        qm = command_at(qc0, qc1, t0 + 0.5 * h, t_knee)
        qb = command_at(qc0, qc1, t0 + h, t_knee)
        for i in range(N_S):  # the substep's tangent starts at [I | 0]
            for j in range(N_S + 1):
                M[i, j] = 1.0 if i == j else 0.0
        _stage_tangent(x, qa, f_in, p, M, A, G, K1)
        for i in range(N_S):
            g0[i] = G[i]
        k1 = _deriv(x, qa, f_in, p)
        t = _axpy(x, 0.5 * h, k1)
        for i in range(N_S):
            for j in range(N_S + 1):
                Mt[i, j] = M[i, j] + 0.5 * h * K1[i, j]
        _stage_tangent(t, qm, f_in, p, Mt, A, G, K2)
        k2 = _deriv(t, qm, f_in, p)
        t = _axpy(x, 0.5 * h, k2)
        for i in range(N_S):
            for j in range(N_S + 1):
                Mt[i, j] = M[i, j] + 0.5 * h * K2[i, j]
        _stage_tangent(t, qm, f_in, p, Mt, A, G, K3)
        k3 = _deriv(t, qm, f_in, p)
        t = _axpy(x, h, k3)
        for i in range(N_S):
            for j in range(N_S + 1):
                Mt[i, j] = M[i, j] + h * K3[i, j]
        _stage_tangent(t, qb, f_in, p, Mt, A, G, K4)
        k4 = _deriv(t, qb, f_in, p)
        x = _axpy(x, h / 6.0, _rk4_sum(k1, k2, k3, k4))
        for i in range(N_S):
            for j in range(N_S + 1):
                M[i, j] = M[i, j] + h / 6.0 * (K1[i, j] + 2.0 * (K2[i, j] + K3[i, j])
                                               + K4[i, j])
        # Phi <- Phi_i Phi, Gamma <- Phi_i Gamma + Gamma_i, Q_d <- Phi_i Q_d Phi_i^T + ...
        # The products skip M[3:, :3] and M[3:, 6]: exact zeros (A[3:, :3] = 0, G[3:] = 0:
        # the reference model does not see the plant), which leave the sums as they were (see
        # _stage_tangent)
        for i in range(N_S):
            m0 = 0 if i < N_X else N_X
            acc = M[i, N_S]
            for j in range(m0, N_S):
                acc += M[i, j] * Gam[j]
            gk[i] = acc
            for j in range(N_S):
                a2 = 0.0
                for m in range(m0, N_S):
                    a2 += M[i, m] * Phi[m, j]
                W[i, j] = a2
        for i in range(N_S):
            Gam[i] = gk[i]
            for j in range(N_S):
                Phi[i, j] = W[i, j]
        for i in range(N_S):
            m0 = 0 if i < N_X else N_X
            for j in range(N_S):
                a2 = 0.0
                for m in range(m0, N_S):
                    a2 += M[i, m] * Qd[m, j]
                W[i, j] = a2
        for i in range(N_S):
            for j in range(N_S):
                m0 = 0 if j < N_X else N_X
                a2 = 0.0
                for m in range(m0, N_S):
                    a2 += W[i, m] * M[j, m]
                W2[i, j] = a2 + g0[i] * g0[j] * q_valve * h
            W2[i, i] += q_state[i] * h
        for i in range(N_S):
            for j in range(N_S):
                Qd[i, j] = W2[i, j]
    for i in range(N_S):
        s[i] = x[i]
        for j in range(i + 1, N_S):
            v = 0.5 * (Qd[i, j] + Qd[j, i])
            Qd[i, j] = v
            Qd[j, i] = v


@jit
def command_timing_noise(s, qc0, qc1, f_in, dt, n_sub, prm, Q):
    """``Q += e e^T / 12`` (6, 6): the state uncertainty of a command change at an unknown
    instant of the interval.

    ``e`` is the difference between the states at the end with the command at ``qc1`` all
    along (changed at the start) and at ``qc0`` all along (changed at the end); the model's
    linear profile sits between, and a change instant uniform over the interval leaves an
    error of variance ``|e|^2 / 12`` along ``e``. ``s`` (6,) is not modified.
    """
    if qc1 == qc0:
        return
    sa = s.copy()
    sb = s.copy()
    dummy = np.empty((N_S, N_S))
    dg = np.empty(N_S)
    qs = np.zeros(N_S)
    propagate(sa, qc1, qc1, f_in, dt, dt, n_sub, prm, False, 0.0, qs, dummy, dg, dummy)
    propagate(sb, qc0, qc0, f_in, dt, dt, n_sub, prm, False, 0.0, qs, dummy, dg, dummy)
    for i in range(N_S):
        ei = sa[i] - sb[i]
        for j in range(N_S):
            Q[i, j] += ei * (sa[j] - sb[j]) / 12.0
