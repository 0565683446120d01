"""One surface's IOTSEKF and RTS-EKF step in numba: the implementation the monitor runs.

``servo_filters.ServoFilters`` wraps it (see that module for the model and the choices); the
numpy reference of the equivalence test is ``tests/reference/servo_filters.py``, which chains
the same kernels of ``models/_servo_jit.py``, ``filters/_iotsekf_jit.py`` and
``filters/_three_step_jit.py`` from Python. One surface and SURF sample per ``surface_step``,
on a packed state (``S_*`` offsets) and a configuration vector (``C_*``); writes the output row
(``O_*`` of ``servo_filters``). ``surfaces_step`` steps every surface of a vehicle in one call
(the monitor's path: one dispatch per SURF sample). Loaded through ``gcs_monitor.core.kernels``.
"""
# ruff: noqa: N803, N806, E741
# mypy: disable-error-code="no-untyped-def"

from __future__ import annotations

import math

import numba
import numpy as np

from gcs_monitor.filters._iotsekf_jit import step as iotsekf_step
from gcs_monitor.filters._three_step_jit import predict_covariance, update
from gcs_monitor.models._servo_jit import ndi, propagate

# this file calls the jitted functions of these files: see gcs_monitor.core.kernels
KERNEL_DEPENDENCIES = {
    "gcs_monitor.models._servo_jit": "729cb11acdea8013",
    "gcs_monitor.filters._iotsekf_jit": "1ee067051d035b30",
    "gcs_monitor.filters._three_step_jit": "e27af0ed83669903",
}

jit = numba.njit(cache=True, fastmath=False, nogil=True)

N = 6  # [x1, x2, x3, r, r', r'']
# packed state: the IOTSEKF in _iotsekf_jit.step's out_state layout, then the RTS-EKF, then
# the command memory
S_IOTS = 0  # x_bar (6), P_bar (36), f (1), Pf (1), V (6), x_hat (6), Px (36)
N_IOTS = N + N * N + 1 + 1 + N + N + N * N
S_XBAR, S_PBAR, S_F, S_PF, S_V, S_XHAT, S_PX = (0, 6, 42, 43, 44, 50, 56)
S_XNOM = N_IOTS  # RTS-EKF: x_nom (6), P_nom (36), f_out (2), Pf_out (4)
S_PNOM = S_XNOM + N
S_FOUT = S_PNOM + N * N
S_PFOUT = S_FOUT + 2
S_QCOM = S_PFOUT + 4  # the rod command of the last sample
S_QPREV = S_QCOM + 1  # the one before (NaN until known)
S_JN = S_QPREV + 1  # |second differences| of the command seen (count, ring index)
S_JIDX = S_JN + 1
S_JBUF = S_JIDX + 1  # the last JIT_MAX |second differences| of the rod command
JIT_MAX = 64
S_XE = S_JBUF + JIT_MAX  # the nominal servo with every command change at the start of its
# interval (S_XE) and at its end (S_XL)
S_XL = S_XE + N  # ... and at its end
# the command timing identified from the rod (see identify_lead): per candidate lead the
# discounted sum of squared rod errors and its nominal servo since the last anchor, the
# candidate in use (-1: not chosen yet), the samples since the anchor, and the sample interval
# the candidates are fractions of (0: none seen yet)
LEAD_FRACTIONS = (0.0, 0.25, 0.5, 1.0)
N_LEAD = len(LEAD_FRACTIONS)
LEAD_SMOOTH = 0.5  # an interval teaches the lead when |second difference| <= this x |first|
LEAD_CLIP_SIGMAS = 10.0  # rod errors clipped at this many rod-noise sigmas
S_LJ = S_XL + N
S_LX = S_LJ + N_LEAD  # N_LEAD x N shadow states
S_LI = S_LX + N_LEAD * N
S_LK = S_LI + 1
S_DTREF = S_LK + 1
S_LFREEZE = S_DTREF + 1  # set by the caller while the surface is in alarm: nothing learnt
S_QMAX = S_LFREEZE + 1  # the largest |rod command| seen since the start
S_JHOLD = S_QMAX + 1  # the unseen-command spread of the last sample not held at the limit
S_QLIM = S_JHOLD + 1  # |rod command| the command was seen held at (the limit; 0: none yet)
S_QSINCE = S_QLIM + 1  # samples since the last interval with a sample at the limit
N_STATE = S_QSINCE + 1
# configuration vector
(C_GAIN, C_STROKE, C_ROD_SIG, C_SURF_SIG, C_SUBSTEP, C_QVALVE, C_QS0, C_QS1, C_QS2,
 C_FRATE, C_GATE, C_LEAD, C_STEP_NOISE, C_JIT_NOISE, C_JIT_WINDOW, C_BLEND, C_LEAD_TAU,
 C_LEAD_SWITCH, C_LEAD_SEGMENT) = range(19)
N_CFG = 19
# output row (servo_filters.O_*)
(O_F_IN, O_U, O_X1, O_X2, O_X3, O_N1, O_N2, O_N3, O_F_ROD, O_F_SURF, O_NU, O_S, O_Q_COM,
 O_Y_ROD, O_Y_SURF, O_SF_ROD, O_SF_D, O_JIT, O_LEAD, O_ENV) = range(20)
N_OUT = 20
OK = 0
SPREAD_PER_RMS = 0.5  # sqrt(1.5) / sqrt(6)
JIT_TRIM = 2  # largest second differences left out of the spread (a step's pair)


@jit
def _held(s0, q, f_in, dt, n_sub, prm, out):
    """``out`` = the state after ``dt`` from ``s0`` with the command held at ``q``."""
    for i in range(N):
        out[i] = s0[i]
    dummy = np.empty((N, N))
    dg = np.empty(N)
    qs = np.zeros(N)
    propagate(out, q, q, f_in, dt, dt, n_sub, prm, False, 0.0, qs, dummy, dg, dummy)


@jit
def command_noise(s0, qc0, qc1, jit, f_in, dt, n_sub, prm, step_noise, jit_noise, Q):
    """``Q`` (6, 6) = the covariance of the command's unknown profile inside the interval at
    ``s0``: ``e e^T / 12`` with ``e`` the end-state difference between the command at ``qc1``
    and at ``qc0`` all along (a change at an unknown instant), plus ``3 e_j e_j^T / 12`` with
    ``e_j`` that of a change by ``jit`` (unseen samples off the line over half the interval on
    average); ``models._servo_jit.command_timing_noise``'s formula, sharing the ``qc0`` run."""
    for i in range(N):
        for j in range(N):
            Q[i, j] = 0.0
    if not step_noise and not (jit_noise and jit > 0.0):
        return
    s0c = np.empty(N)
    _held(s0, qc0, f_in, dt, n_sub, prm, s0c)
    e = np.empty(N)
    if step_noise and qc1 != qc0:
        s1c = np.empty(N)
        _held(s0, qc1, f_in, dt, n_sub, prm, s1c)
        for i in range(N):
            e[i] = s1c[i] - s0c[i]
        for i in range(N):
            for j in range(N):
                Q[i, j] += e[i] * e[j] / 12.0
    if jit_noise and jit > 0.0:
        sj = np.empty(N)
        _held(s0, qc0 + jit, f_in, dt, n_sub, prm, sj)
        for i in range(N):
            e[i] = sj[i] - s0c[i]
        for i in range(N):
            for j in range(N):
                Q[i, j] += 3.0 * (e[i] * e[j] / 12.0)


@jit
def unseen_spread(st, qc0, qc1, dt, cfg):
    """The spread of the command samples the SURF stream did not carry (m of rod) and the ring
    buffer's next count and index (-1, -1: no new second difference).

    ``SPREAD_PER_RMS`` x the RMS of ``|q_k - 2 q_{k-1} + q_{k-2}|`` over the jitter window (the
    newest included) without its ``JIT_TRIM`` largest values: for a command with white jitter
    of sigma per autopilot sample at twice the SURF rate, the second differences of the samples
    seen have sigma ``sqrt(6)`` sigma and an unseen sample lies ``sqrt(1.5)`` sigma off the line
    through its neighbours; the trim drops the pair of values a command step leaves (the step
    noise covers those), a one-sample spike keeps its third.

    A command held at its limit: three seen samples exactly equal at the largest deflection
    commanded so far are an autopilot's clipped demand (its limit is not in the telemetry;
    from then on ``S_QLIM``, the fifth value returned), and the unseen samples between them
    leave the limit whenever the demand comes back inside it (a rudder banging between its
    limits in turbulence: the rod leaves the stop between two SURF samples). Their zero second
    differences say nothing of those samples: over every interval with a sample at the limit,
    and until the jitter window has no such interval left (``S_QSINCE``, the sixth value
    returned: samples since the last), the spread does not fall below its value on the last
    sample before (``S_JHOLD``, the fourth value returned). Not only while three samples are
    equal: a demand that leaves the limit for a seen sample or two and comes back has the
    same unseen excursions, and the window's zeros and the trim leave its bounces a tenth of
    their spread (the Wan2018 campaign's runs 42 and 111: the rod 6-12 mm inside the limit
    the samples showed, read as valve faults of 0.05-0.13 in turbulence). A command that was
    quiet when it got there (a 3-2-1-1 plateau) keeps the spread it had, none.
    """
    qprev = st[S_QPREV]
    qlim = st[S_QLIM]
    if cfg[C_JIT_NOISE] == 0.0 or qprev != qprev:
        return 0.0, -1, -1, 0.0, qlim, st[S_QSINCE]
    jn = int(st[S_JN])
    jidx = int(st[S_JIDX])
    n = max(3, min(JIT_MAX, int(round(cfg[C_JIT_WINDOW] / dt))))
    vals = np.empty(n)
    vals[0] = abs(qc1 - 2.0 * qc0 + qprev)
    have = min(jn, n - 1)
    for i in range(have):  # the newest ring entries, backwards from the last written
        vals[1 + i] = st[S_JBUF + (jidx - 1 - i) % JIT_MAX]
    m = 1 + have
    v = np.sort(vals[:m])
    keep = m - JIT_TRIM if m > 2 * JIT_TRIM else m
    acc = 0.0
    for i in range(keep):
        acc += v[i] * v[i]
    spread = SPREAD_PER_RMS * math.sqrt(acc / m)
    if qc1 == qc0 and qc0 == qprev and abs(qc1) >= st[S_QMAX] > 0.0:  # held at the limit
        qlim = abs(qc1)
    since = st[S_QSINCE] + 1.0
    if qlim > 0.0 and (abs(qc0) >= qlim or abs(qc1) >= qlim):  # an interval at the limit
        since = 0.0
    if qlim > 0.0 and since < n:  # at the limit, or its zeros still in the window
        hold = st[S_JHOLD]
        if hold > spread:
            spread = hold
    else:
        hold = spread
    return spread, min(jn + 1, JIT_MAX), (jidx + 1) % JIT_MAX, hold, qlim, since


@jit
def nearest_fraction(lead_s, dt_ref):
    """Index of the candidate fraction of ``dt_ref`` nearest to ``lead_s``."""
    best, err = 0, math.inf
    for j in range(N_LEAD):
        e = abs(LEAD_FRACTIONS[j] * dt_ref - lead_s)
        if e < err:
            best, err = j, e
    return best


@jit
def command_lead(st, dt, cfg):
    """``(lead_s, index, dt_ref)``: how long before a SURF sample the command it reports took
    effect, as the filters use it this interval.

    The configured ``command_lead_s`` when the identification is off (``C_LEAD_TAU = 0``);
    otherwise the candidate ``LEAD_FRACTIONS[index] x dt_ref`` in use (``dt_ref``: the shortest
    SURF interval seen, the stream's period; a lost sample only lengthens an interval), first
    the one nearest the configured lead. The lead is the autopilot's servo-output period
    (a command computed at each loop step and held for one step; the SURF sample reports the
    newest): 0 for a loop much faster than SURF, ``dt_ref / 2`` for a loop at twice its rate,
    ``dt_ref`` for one at its rate. A configured period is what the vehicle was said to run at;
    :func:`identify_lead` measures it from the rod.
    """
    dt_ref = st[S_DTREF]
    if dt_ref <= 0.0 or dt < dt_ref:
        dt_ref = dt
    if cfg[C_LEAD_TAU] <= 0.0:
        return cfg[C_LEAD], -1, dt_ref
    li = int(st[S_LI])
    if li < 0:
        li = nearest_fraction(cfg[C_LEAD], dt_ref)
    return LEAD_FRACTIONS[li] * dt_ref, li, dt_ref


@jit
def identify_lead(st, anchor, qc0, qc1, y_rod, dt, dt_ref, li, n_sub, prm, cfg, lj, lx):
    """The candidate lead for the next interval and the identification's new state ``lj``
    (N_LEAD,), ``lx`` (N_LEAD, N); returns ``(index, samples since the anchor)`` (ours; Lu2017
    takes the command as known at every instant).

    Each candidate runs the nominal servo (no fault) with every command change ending
    ``LEAD_FRACTIONS[j] x dt_ref`` before its sample, from a common anchor (``anchor``: the
    IOTSEKF's estimate at the start of the interval, every ``C_LEAD_SEGMENT`` samples) and
    uncorrected in between: a wrong lead shifts the rod by about its rate x the lead error,
    which grows over a segment while the rod noise does not; one-step predictions drown it in
    the noise. ``lj[j] = exp(-dt / tau) J_j + min(|x1_j - y_rod|, LEAD_CLIP_SIGMAS sigma)^2``
    (a fault moves the rod away from every candidate alike; the clip keeps it from deciding).

    Only a smooth command teaches the lead: the ramp between samples stands for a command the
    loop samples at each step, and a step between two samples (``|second difference| >
    LEAD_SMOOTH |first difference|``, also the interval after it) has its own unknown instant.
    Such an interval adds nothing and starts a new segment at the next sample; so does a
    caller's freeze (``S_LFREEZE``: the surface in alarm).

    Returns the index with the smallest sum when the one in use exceeds it by more than
    ``C_LEAD_SWITCH`` rod-noise variances, else ``li``. The rod noise adds the same to every
    sum (the candidates' servos do not see it), so the difference is the evidence: with the
    candidates' rods ``d_k`` apart it is ``sum d_k^2`` plus a cross term of sigma
    ``2 sigma_rod sqrt(sum d_k^2)``: at a margin of 25 variances the evidence is 2.5 of those
    sigmas, and it grows with the square root of the evidence; two candidates that predict
    alike never switch (their sums are equal).
    """
    qprev = st[S_QPREV]
    d1 = qc1 - qc0
    d2 = qc1 - 2.0 * qc0 + qprev
    k = int(st[S_LK])
    if st[S_LFREEZE] != 0.0 or not abs(d2) <= LEAD_SMOOTH * abs(d1):  # NaN qprev: not smooth
        for j in range(N_LEAD):
            lj[j] = st[S_LJ + j]
            for i in range(N):
                lx[j, i] = st[S_LX + j * N + i]
        return li, 0
    lam = math.exp(-dt / cfg[C_LEAD_TAU])
    clip = LEAD_CLIP_SIGMAS * cfg[C_ROD_SIG]
    dummy = np.empty((N, N))
    dg = np.empty(N)
    qs = np.zeros(N)
    for j in range(N_LEAD):
        for i in range(N):
            lx[j, i] = anchor[i] if k == 0 else st[S_LX + j * N + i]
        knee = max(dt - LEAD_FRACTIONS[j] * dt_ref, 0.0)
        s = lx[j]
        propagate(s, qc0, qc1, 0.0, dt, knee, n_sub, prm, False, 0.0, qs, dummy, dg, dummy)
        e = min(abs(s[0] - y_rod), clip)
        lj[j] = lam * st[S_LJ + j] + e * e
    k += 1
    if k >= cfg[C_LEAD_SEGMENT]:
        k = 0
    best = li
    for j in range(N_LEAD):
        if lj[j] < lj[best]:
            best = j
    if lj[li] - lj[best] > cfg[C_LEAD_SWITCH] * cfg[C_ROD_SIG] * cfg[C_ROD_SIG]:
        return best, k
    return li, k


@jit
def surface_step(st, dt, cmd_rad, y_rod, y_surf_rad, prm, cfg, out):
    """One SURF interval of one surface's IOTSEKF and RTS-EKF, in place on ``st``
    (``servo_filters.ServoFilters.step``). Returns 0, or the failing filter's code (1-2: the
    IOTSEKF's, 3: the RTS-EKF's update); on a failure ``st`` is left as it was."""
    stroke = cfg[C_STROKE]
    gain = cfg[C_GAIN]
    qc0 = st[S_QCOM]
    q = cmd_rad / gain
    qc1 = stroke if q > stroke else (-stroke if q < -stroke else q)
    n_sub = max(1, int(math.ceil(dt / cfg[C_SUBSTEP] - 1e-9)))
    lead, li, dt_ref = command_lead(st, dt, cfg)
    knee = max(dt - lead, 0.0)
    qv = cfg[C_QVALVE]
    qs = np.zeros(N)
    qs[0] = cfg[C_QS0]
    qs[1] = cfg[C_QS1]
    qs[2] = cfg[C_QS2]
    jitv, jn, jidx, jhold, qlim, qsince = unseen_spread(st, qc0, qc1, dt, cfg)
    # IOTSEKF over [x, r]
    x_bar = st[S_XBAR:S_XBAR + N].copy()
    P_bar = st[S_PBAR:S_PBAR + N * N].copy().reshape((N, N))
    f = st[S_F:S_F + 1].copy()
    Pf = st[S_PF:S_PF + 1].copy().reshape((1, 1))
    V = st[S_V:S_V + N].copy().reshape((N, 1))
    x_hat = st[S_XHAT:S_XHAT + N].copy()
    f0 = f[0]
    lj = np.empty(N_LEAD)
    lx = np.empty((N_LEAD, N))
    li_next = li
    lk = 0
    if li >= 0:
        li_next, lk = identify_lead(st, x_hat, qc0, qc1, y_rod, dt, dt_ref, li, n_sub, prm,
                                    cfg, lj, lx)
    Qt = np.empty((N, N))
    command_noise(x_hat, qc0, qc1, jitv, f0, dt, n_sub, prm, cfg[C_STEP_NOISE] != 0.0,
                  cfg[C_JIT_NOISE] != 0.0, Qt)
    s = x_hat.copy()
    Phi = np.empty((N, N))
    gam = np.empty(N)
    Qd = np.empty((N, N))
    propagate(s, qc0, qc1, f0, dt, knee, n_sub, prm, True, qv, qs, Phi, gam, Qd)
    for i in range(N):
        for j in range(N):
            Qd[i, j] += Qt[i, j]
    xbp = np.empty(N)
    if cfg[C_BLEND] != 0.0:
        # x_bar_{k|k-1} + U f_hat = the nonlinear prediction of x_hat: F(x_hat) - (Phi V + G) f
        for i in range(N):
            acc = gam[i]
            for j in range(N):
                acc += Phi[i, j] * V[j, 0]
            xbp[i] = s[i] - acc * f0
    else:  # Lu2017 eq. 17 as printed
        for i in range(N):
            xbp[i] = x_bar[i]
        d6 = np.empty((N, N))
        dg = np.empty(N)
        propagate(xbp, qc0, qc1, 0.0, dt, knee, n_sub, prm, False, qv, qs, d6, dg, d6)
    Gam = np.empty((N, 1))
    for i in range(N):
        Gam[i, 0] = gam[i]
    rf = cfg[C_FRATE] * dt
    Qf = np.empty((1, 1))
    Qf[0, 0] = rf * rf
    H1 = np.zeros((1, N))
    H1[0, 0] = 1.0
    y1 = np.empty(1)
    y1[0] = y_rod
    R1 = np.empty((1, 1))
    R1[0, 0] = cfg[C_ROD_SIG] * cfg[C_ROD_SIG]
    ots = np.empty(N_IOTS)
    oin = np.empty(3)
    code = iotsekf_step(xbp, Phi, Gam, Qd, Qf, x_bar, P_bar, f, Pf, V, H1, y1, R1,
                        cfg[C_GATE], ots, oin)
    if code != OK:
        return code
    # RTS-EKF: the nominal servo over [x, r], the same command-sampling covariance
    xn = st[S_XNOM:S_XNOM + N].copy()
    Pn = st[S_PNOM:S_PNOM + N * N].copy().reshape((N, N))
    Phi_r = np.empty((N, N))
    Qd_r = np.empty((N, N))
    propagate(xn, qc0, qc1, 0.0, dt, knee, n_sub, prm, True, qv, qs, Phi_r, gam, Qd_r)
    for i in range(N):
        for j in range(N):
            Qd_r[i, j] += Qt[i, j]
    Pp = np.empty((N, N))
    predict_covariance(Pn, Phi_r, Qd_r, Pp)
    H2 = np.zeros((2, N))
    H2[0, 0] = 1.0
    H2[1, 0] = 1.0
    F2 = np.eye(2)
    R2 = np.zeros((2, 2))
    R2[0, 0] = cfg[C_ROD_SIG] * cfg[C_ROD_SIG]
    ss = cfg[C_SURF_SIG] / gain
    R2[1, 1] = ss * ss
    y_surf = y_surf_rad / gain
    y2 = np.empty(2)
    y2[0] = y_rod
    y2[1] = y_surf
    hx2 = np.empty(2)
    hx2[0] = xn[0]
    hx2[1] = xn[0]
    xr = np.empty(N)
    Pr = np.empty((N, N))
    fr = np.empty(2)
    Pfr = np.empty((2, 2))
    nu2 = np.empty(2)
    sd2 = np.empty(2)
    ra2 = np.empty(2)
    if not update(xn, Pp, hx2, H2, F2, y2, R2, cfg[C_GATE], xr, Pr, fr, Pfr, nu2, sd2, ra2):
        return 3
    # the timing envelope of the nominal servo: the same command sequence with each change at
    # the start and at the end of its interval, propagated through the nonlinear loop
    xe = st[S_XE:S_XE + N].copy()
    xl = st[S_XL:S_XL + N].copy()
    _held(st[S_XE:S_XE + N], qc1, 0.0, dt, n_sub, prm, xe)
    _held(st[S_XL:S_XL + N], qc0, 0.0, dt, n_sub, prm, xl)
    env = xe[0] - xl[0]
    # commit
    for i in range(N_IOTS):
        st[S_IOTS + i] = ots[i]
    for i in range(N):
        st[S_XNOM + i] = xr[i]
        for j in range(N):
            st[S_PNOM + i * N + j] = Pr[i, j]
    st[S_FOUT] = fr[0]
    st[S_FOUT + 1] = fr[1]
    for i in range(2):
        for j in range(2):
            st[S_PFOUT + 2 * i + j] = Pfr[i, j]
    if jn >= 0:  # a new second difference enters the ring
        st[S_JBUF + int(st[S_JIDX])] = abs(qc1 - 2.0 * qc0 + st[S_QPREV])
        st[S_JN] = jn
        st[S_JIDX] = jidx
    st[S_QPREV] = qc0
    st[S_QCOM] = qc1
    st[S_JHOLD] = jhold
    st[S_QLIM] = qlim
    st[S_QSINCE] = qsince
    if abs(qc1) > st[S_QMAX]:
        st[S_QMAX] = abs(qc1)
    for i in range(N):
        st[S_XE + i] = xe[i]
        st[S_XL + i] = xl[i]
    if li >= 0:
        for j in range(N_LEAD):
            st[S_LJ + j] = lj[j]
            for i in range(N):
                st[S_LX + j * N + i] = lx[j, i]
        st[S_LI] = li_next
        st[S_LK] = lk
    st[S_DTREF] = dt_ref
    # outputs
    xh = st[S_XHAT:S_XHAT + N].copy()
    fn = st[S_F]
    grad = np.empty(3)
    out[O_F_IN] = fn
    out[O_U] = ndi(xh, qc1, prm, grad) + fn
    out[O_X1] = xh[0]
    out[O_X2] = xh[1]
    out[O_X3] = xh[2]
    out[O_N1] = xr[0]
    out[O_N2] = xr[1]
    out[O_N3] = xr[2]
    out[O_F_ROD] = fr[0]
    out[O_F_SURF] = fr[1]
    out[O_NU] = oin[0]
    out[O_S] = oin[1]
    out[O_Q_COM] = qc1
    out[O_Y_ROD] = y_rod
    out[O_Y_SURF] = y_surf
    # the rod output fault's sigma: P^f (eq. 43) and the timing envelope (uniform between
    # its two edges: variance env^2 / 12)
    out[O_SF_ROD] = math.sqrt(max(Pfr[0, 0], 0.0) + env * env / 12.0)
    out[O_SF_D] = math.sqrt(max(Pfr[0, 0] + Pfr[1, 1] - 2.0 * Pfr[0, 1], 0.0))
    out[O_JIT] = jitv
    out[O_LEAD] = lead
    out[O_ENV] = env
    return OK


@jit
def surfaces_step(st, dt, cmd_rad, y_rod, y_surf_rad, prm, cfg, out):
    """``surface_step`` of every surface ``k`` in turn: state row ``st[k]`` (n, N_STATE),
    command, rod and surface samples ``[k]``, output row ``out[k]`` (n, N_OUT), the same
    ``prm`` and ``cfg`` for all. Returns -1, or the index of the first surface whose step
    failed (it and the surfaces after it are left as they were; the caller restarts all)."""
    for k in range(st.shape[0]):
        if surface_step(st[k], dt, cmd_rad[k], y_rod[k], y_surf_rad[k], prm, cfg,
                        out[k]) != OK:
            return k
    return -1
