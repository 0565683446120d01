"""Iterated optimal two-stage EKF (IOTSEKF) and its adaptive version (ATSEKF), Lu2016 sec. 3.1.

The filter estimates a state x and an input fault f (random walk, Lu2016 sec. 3.1) with two
coupled filters: a bias-free filter (eqs. 31-39), a bias filter (eqs. 40-44), the coupling
equations (45-50) and the blend (51-52). The ATSEKF adapts ``Q^f`` by covariance matching
(eqs. 53-58). It knows nothing about aircraft; the model object supplies the propagation,
the Jacobians and the output function (see :class:`TwoStageModel`).

Choices where the printed text is ambiguous (each is marked ``# Lu2016 note`` below and
explained in docs/papers-notes.md):

1. F and G (eq. 34) are evaluated at the blended estimate ``x_hat_{k-1|k-1}`` with the
   fault-corrected input ``u_m - f_hat``, the point an augmented-state EKF would use; the
   print says ``x_bar_{k-1|k-1}``. Identical for linear models.
2. Gamma (eq. 34) is ``int_0^dt exp(F s) ds G`` (the model's job; see kinematics.discretise).
3. The innovation gamma_j of eq. 54 is printed as ``y - h(Phi x_hat + Gamma f_hat)``, which
   drops the input term of a nonlinear model. We use the bias-filter innovation of eq. 43,
   ``y - h(x_bar_{k|k-1}) - S_k f_hat_{k|k-1}``, which to first order is
   ``y - h(x_bar_{k|k-1} + U_k f_hat)`` = y minus the output of the full-state prediction
   (two-stage identity ``x_hat_{k|k-1} = x_bar_{k|k-1} + U_k f_hat``).
4. Eq. 53 divides ``H Gamma Q Gamma^T H^T`` by dt and eq. 57 multiplies by dt^2; both kept as
   printed. Only the diagonal of C_r is needed because only diag(Q_hat) is used (eq. 58).
5. The Q^f adaptation starts once the window holds N innovations; before, Q^f keeps its
   initial value.

``Q^{xf}``, the state/fault noise cross covariance, is zero (Lu2016 sec. 3.1, after its
ref. [30]).

Where each step runs. After the first ``n_iterated_steps`` steps, a step with the built-in
discretisation runs in the numba kernels of ``filters/_two_stage_jit.py`` (:func:`_step_compiled`;
:class:`PackedTwoStage` for the estimator's hot path). The iterated first steps, and steps with a
caller's discretiser, run :func:`_step_numpy`: the kernel does not iterate, because every
iteration of eq. 37 evaluates the model's ``h`` and ``H`` at the new iterate, a Python model
object. Both paths chain the same equation segments of the kernel module (``discretise``
eqs. 33-34; ``coupling`` 41, 47, 49; ``prediction`` 32, 45-46; ``innovation_covariance`` 36;
``joseph`` 39, 44; ``bias_terms`` 42-43, 48; ``blend`` 43-44, 50-52). Written twice, on purpose:

* the Cholesky factorisations and solves of eqs. 36, 42 and 49 -- LAPACK ``potrf``/``potrs``
  here (:mod:`gcs_monitor.filters.covariance`), ``filters/_linalg.py``'s loops in the kernel;
* the ``Q^f`` adaptation of eqs. 53, 57-58 -- :func:`adapt_qf` (numpy sums, LU solve) here,
  sequential sums and a Gauss-Jordan inverse in the kernel's ``update``.

Each pair agrees to round-off, not bit for bit, and each side is pinned by the monitor's recorded
replays (the first ten steps after every (re)start run here, all later ones in the kernel), so
neither can take the other's form without changing the monitor's output. The iterated form of
eq. 37 exists only here; the kernel has its non-iterated case ``eta_1 = x_bar_{k|k-1}``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np

from gcs_monitor.core.kernels import load_kernels
from gcs_monitor.core.types import Mat, Vec
from gcs_monitor.filters.covariance import (
    all_finite,
    cho_factor_lower,
    cho_solve_lower,
    eye,
    gain,
    solve_general,
)
from gcs_monitor.filters.ekf import Innovation, make_innovation


class TwoStageModel(Protocol):
    """What the two-stage filter needs from a model ``x_dot = f(x, u - f) `` , ``y = h(x)``."""

    def propagate(self, x: Vec, u0: Vec, u1: Vec, dt_s: float) -> Vec:
        """``x + int f(x, u, 0) dt`` over one step, input from u0 to u1 (Lu2016 eq. 31)."""
        ...

    def jacobians(self, x: Vec, u: Vec) -> tuple[Mat, Mat]:
        """``(F, G) = (df/dx, df/df)`` at (x, u) (Lu2016 eqs. 13, 34)."""
        ...

    def h(self, x: Vec) -> Vec: ...

    def h_jac(self, x: Vec) -> Mat: ...


class Discretiser(Protocol):
    def __call__(self, F: Mat, G: Mat, dt_s: float) -> tuple[Mat, Mat]: ...


def discretise_series(F: Mat, G: Mat, dt_s: float) -> tuple[Mat, Mat]:
    """Transition ``Phi = exp(F dt)`` and input matrix ``Gamma = int_0^dt exp(F s) ds G``.

    Lu2016 eqs. 33-34, series truncated after ``(F dt)^3 / 3!``: |F dt| ~ 1e-2 at 100 Hz, so
    the first neglected term is ~1e-9 relative. Eq. 34 prints ``Gamma = int Phi G dt``; the
    integrand is ``exp(F s)`` (s from 0 to dt), not the constant ``Phi`` -- we use the former:
    ``Gamma = (sum_k (F dt)^k / (k+1)!) dt G``. Computed by the kernel ``discretise``
    (``filters/_two_stage_jit.py``), the one both paths of the filter use.
    """
    kern = load_kernels("gcs_monitor.filters._two_stage_jit")
    phi, gam = kern.discretise(F, G, float(dt_s))
    return phi, gam


@dataclass(frozen=True, slots=True)
class TwoStageNoise:
    """Noise covariances of the two-stage filter.

    Attributes
    ----------
    Q : (b, b) input (IMU) noise covariance, Lu2016 eq. 56
    R : (m, m) measurement noise covariance, Lu2016 eq. 55

    The state/fault cross covariance ``Q^{xf}`` is zero (module docstring).
    """

    Q: Mat
    R: Mat


@dataclass(frozen=True, slots=True)
class TwoStageConfig:
    """Algorithm settings (Lu2016 sec. 3.1).

    Attributes
    ----------
    eps0 : iteration stop threshold epsilon_0 (Lu2016: 1e-8)
    n_iterated_steps : the iterated update runs only in the first steps (Lu2016: ten)
    max_iterations : cap on the iterations of one step (not given in Lu2016)
    adapt : True = ATSEKF (covariance matching of Q^f, eqs. 53-58); False = IOTSEKF
    window_n : moving-window size N of eq. 53 (Lu2016: 10)
    gate_sigma : gate of the normalised innovation test ratio (reporting only)
    """

    eps0: float = 1.0e-8
    n_iterated_steps: int = 10
    max_iterations: int = 20
    adapt: bool = True
    window_n: int = 10
    gate_sigma: float = 3.0


@dataclass(frozen=True, slots=True)
class TwoStageState:
    """Two-stage filter state after step k.

    Attributes
    ----------
    x_bar, P_bar : (n,), (n, n) bias-free estimate and covariance (eqs. 38-39)
    f, Pf : (b,), (b, b) fault estimate and covariance (eqs. 43-44)
    V : (n, b) blending matrix (eq. 50)
    Qf : (b, b) fault random-walk covariance used by the next prediction (eq. 41 / 57)
    x, Px : (n,), (n, n) blended state estimate and covariance (eqs. 51-52)
    k : number of completed steps
    gamma2 : (N, m) squared innovations of the last N steps (ring buffer, eq. 53)
    """

    x_bar: Vec
    P_bar: Mat
    f: Vec
    Pf: Mat
    V: Mat
    Qf: Mat
    x: Vec
    Px: Mat
    k: int
    gamma2: Mat


def two_stage_init(
    x0: Vec, P0: Mat, f0: Vec, Pf0: Mat, Qf0: Mat, *, m: int, window_n: int
) -> TwoStageState:
    """Initial state with zero state/fault cross covariance (V_0 = 0)."""
    n, b = x0.size, f0.size
    return TwoStageState(
        x_bar=x0.copy(),
        P_bar=P0.copy(),
        f=f0.copy(),
        Pf=Pf0.copy(),
        V=np.zeros((n, b)),
        Qf=Qf0.copy(),
        x=x0.copy(),
        Px=P0.copy(),
        k=0,
        gamma2=np.zeros((window_n, m)),
    )


def _fail(s: TwoStageState, nu: Vec, S: Mat, gate: float) -> tuple[TwoStageState, Innovation]:
    return s, make_innovation(nu, S, gate, False)


def two_stage_step(
    s: TwoStageState,
    model: TwoStageModel,
    u_prev: Vec,
    u_now: Vec,
    y: Vec,
    dt_s: float,
    noise: TwoStageNoise,
    cfg: TwoStageConfig,
    *,
    discretise: Discretiser | None = None,
) -> tuple[TwoStageState, Innovation]:
    """One IOTSEKF / ATSEKF step from t_{k-1} to t_k (Lu2016 eqs. 31-58).

    Parameters
    ----------
    s : state at k-1
    model : model at this step's parameters
    u_prev, u_now : (b,) measured inputs u_m at t_{k-1} and t_k
    y : (m,) measurement at t_k
    dt_s : t_k - t_{k-1} (s)
    noise : Q, R
    cfg : algorithm settings
    discretise : (F, G, dt) -> (Phi, Gamma); None = :func:`discretise_series` (eqs. 33-34)

    Returns
    -------
    The state at k and the innovation record of the bias-filter innovation (eq. 43) with the
    full innovation covariance ``H P_bar H^T + R + S P^f S^T``. On a numerical failure the
    input state is returned unchanged with ``numerics_ok = False``; the caller resets.
    The step runs in the numba kernels once the iterations are over, in :func:`_step_numpy`
    before, or with a caller's ``discretise`` (module docstring).
    """
    if discretise is None and s.k >= cfg.n_iterated_steps:
        return _step_compiled(s, model, u_prev, u_now, y, dt_s, noise, cfg)
    return _step_numpy(
        s, model, u_prev, u_now, y, dt_s, noise, cfg, discretise or discretise_series
    )


def _step_compiled(
    s: TwoStageState,
    model: TwoStageModel,
    u_prev: Vec,
    u_now: Vec,
    y: Vec,
    dt_s: float,
    noise: TwoStageNoise,
    cfg: TwoStageConfig,
) -> tuple[TwoStageState, Innovation]:
    """The non-iterated step through the numba kernels (``predict``, ``update``)."""
    _jit = load_kernels("gcs_monitor.filters._two_stage_jit")
    F, G = model.jacobians(s.x, u_prev - s.f)  # Lu2016 note 1
    xb_prop = model.propagate(s.x_bar, u_prev, u_now, dt_s)  # eq. 31 without ubar
    ok, Gam, U, ubar, P_pred, Pf_pred = _jit.predict(
        F, G, dt_s, s.V, s.Pf, s.Qf, s.f, s.P_bar, noise.Q
    )
    m = y.size
    if not ok:
        return _fail(s, np.full(m, np.nan), np.full((m, m), np.nan), cfg.gate_sigma)
    x_pred = xb_prop + ubar  # eq. 31
    hx = model.h(x_pred)
    H = model.h_jac(x_pred)
    out = _jit.update(
        x_pred,
        P_pred,
        hx,
        H,
        y,
        noise.R,
        U,
        Pf_pred,
        s.f,
        s.gamma2,
        s.k,
        cfg.adapt,
        Gam,
        noise.Q,
        s.Qf,
        dt_s,
        cfg.gate_sigma,
    )
    ok, x_bar, P_bar, f_new, Pf_new, V, x_hat, Px, gamma2, Qf_next, nu, s_diag, ratio = out
    innov = Innovation(nu=nu, S_diag=s_diag, test_ratio=ratio, numerics_ok=ok)
    if not ok:
        return s, innov
    return (
        TwoStageState(
            x_bar=x_bar,
            P_bar=P_bar,
            f=f_new,
            Pf=Pf_new,
            V=V,
            Qf=Qf_next,
            x=x_hat,
            Px=Px,
            k=s.k + 1,
            gamma2=gamma2,
        ),
        innov,
    )


def _step_numpy(
    s: TwoStageState,
    model: TwoStageModel,
    u_prev: Vec,
    u_now: Vec,
    y: Vec,
    dt_s: float,
    noise: TwoStageNoise,
    cfg: TwoStageConfig,
    discretise: Discretiser,
) -> tuple[TwoStageState, Innovation]:
    """The step with LAPACK's solves, iterated in the first steps (module docstring).

    The kernel's equation segments between its own factorisations, the iteration of eq. 37
    and the adaptation :func:`adapt_qf` (eqs. 53-58).
    """
    kern = load_kernels("gcs_monitor.filters._two_stage_jit")
    f_hat = s.f
    # Lu2016 note 1: linearise at the blended estimate with the corrected input
    F, G = model.jacobians(s.x, u_prev - f_hat)
    Phi, Gam = discretise(F, G, dt_s)  # eqs. 33-34
    Ubar, Pf_pred, W = kern.coupling(Phi, Gam, s.V, s.Pf, s.Qf)  # eqs. 47, 41
    Lf, ok = cho_factor_lower(Pf_pred)
    m = y.size
    if not ok:
        return _fail(s, np.full(m, np.nan), np.full((m, m), np.nan), cfg.gate_sigma)
    U = Ubar + cho_solve_lower(Lf, W.T).T  # eq. 49: U = Ubar + (Qxf - Ubar Qf) Pf_pred^{-1}
    ubar, P_pred = kern.prediction(Phi, Gam, noise.Q, s.P_bar, Ubar, U, W, f_hat)  # 45-46, 32
    x_pred = model.propagate(s.x_bar, u_prev, u_now, dt_s) + ubar  # eq. 31

    # bias-free measurement update, iterated in the first steps (eqs. 35-38)
    R = noise.R
    eta1 = x_pred
    hx_pred = model.h(x_pred)
    hx = hx_pred
    H = model.h_jac(eta1)
    iterate = s.k < cfg.n_iterated_steps
    for _it in range(cfg.max_iterations if iterate else 1):
        PHt, Sx = kern.innovation_covariance(P_pred, H, R)
        K, ok = gain(PHt, Sx)  # eq. 36
        if not ok:
            return _fail(s, y - hx_pred, Sx, cfg.gate_sigma)
        eta2 = x_pred + K @ (y - hx - H @ (x_pred - eta1))  # eq. 37
        if not iterate:
            break
        norm2 = float(np.linalg.norm(eta2))
        eps = float(np.linalg.norm(eta2 - eta1)) / norm2 if norm2 > 0.0 else 0.0
        if eps <= cfg.eps0:
            break
        eta1 = eta2
        hx = model.h(eta1)
        H = model.h_jac(eta1)
    x_bar = eta2  # eq. 38
    P_bar = kern.joseph(P_pred, K, H, R)  # eq. 39

    # bias filter (eqs. 40-44)
    S, PfSt, Sig, gamma = kern.bias_terms(H, U, Pf_pred, Sx, y, hx_pred, f_hat)  # 48, 42, 43
    Kf, ok = gain(PfSt, Sig)  # eq. 42
    # gamma: eq. 43 innovation (= gamma of eq. 54, Lu2016 note 3)
    innov = make_innovation(gamma, Sig, cfg.gate_sigma, ok)
    if not innov.numerics_ok:
        return s, innov
    # eqs. 43-44 (Joseph form, R_eff = Sx) and the blend, eqs. 50-52
    f_new, Pf_new, V, x_hat, Px = kern.blend(U, K, S, x_bar, P_bar, f_hat, Kf, gamma, Pf_pred, Sx)

    gamma2 = s.gamma2.copy()
    nwin = gamma2.shape[0]
    gamma2[s.k % nwin] = gamma * gamma
    k = s.k + 1
    Qf_next = s.Qf
    if cfg.adapt and k >= nwin:
        Qf_next = adapt_qf(gamma2, H, Gam, noise.Q, R, dt_s)
    if not (all_finite(x_hat) and all_finite(Px) and all_finite(f_new)):
        return s, replace(innov, numerics_ok=False)
    return (
        TwoStageState(
            x_bar=x_bar,
            P_bar=P_bar,
            f=f_new,
            Pf=Pf_new,
            V=V,
            Qf=Qf_next,
            x=x_hat,
            Px=Px,
            k=k,
            gamma2=gamma2,
        ),
        innov,
    )


def two_stage_predict(
    s: TwoStageState,
    model: TwoStageModel,
    u_prev: Vec,
    u_now: Vec,
    dt_s: float,
    noise: TwoStageNoise,
    *,
    discretise: Discretiser | None = None,
) -> TwoStageState | None:
    """The time update alone, for a step without a measurement (Lu2016 eqs. 31-34, 41, 45-47,
    49, then eqs. 50-52 with a zero gain).

    With no measurement the bias-free estimate is its prediction (``x_bar = x_bar_{k|k-1}``,
    ``P_bar = P_bar_{k|k-1}``), the fault estimate keeps its value with the grown covariance
    ``P^f_{k|k-1}`` (eq. 41), the coupling is ``V = U`` (eq. 50 with ``K = 0``), and the blend
    of eqs. 51-52 follows. ``Q^f``, the innovation window of eq. 53 and the step count are
    unchanged (no innovation was seen). None on a numerical failure.
    """
    kern = load_kernels("gcs_monitor.filters._two_stage_jit")
    F, G = model.jacobians(s.x, u_prev - s.f)  # Lu2016 note 1
    Phi, Gam = (discretise or discretise_series)(F, G, dt_s)  # eqs. 33-34
    Ubar, Pf_pred, W = kern.coupling(Phi, Gam, s.V, s.Pf, s.Qf)  # eqs. 47, 41
    Lf, ok = cho_factor_lower(Pf_pred)
    if not ok:
        return None
    U = Ubar + cho_solve_lower(Lf, W.T).T  # eq. 49
    ubar, P_pred = kern.prediction(Phi, Gam, noise.Q, s.P_bar, Ubar, U, W, s.f)  # 45-46, 32
    x_bar = model.propagate(s.x_bar, u_prev, u_now, dt_s) + ubar  # eq. 31
    x = x_bar + U @ s.f  # eq. 51
    Px = P_pred + U @ Pf_pred @ U.T  # eq. 52
    if not (all_finite(x) and all_finite(Px)):
        return None
    return replace(s, x_bar=x_bar, P_bar=P_pred, Pf=Pf_pred, V=U, x=x, Px=0.5 * (Px + Px.T))


def adapt_qf(gamma2: Mat, H: Mat, Gam: Mat, Q: Mat, R: Mat, dt_s: float) -> Mat:
    """Covariance-matching update of ``Q^f`` (Lu2016 eqs. 53, 57, 58).

    ``Q_hat = C_r - H Gamma Q Gamma^T H^T / dt - R`` (eq. 53, diagonal only),
    ``Q_tilde = diag(max(0, Q_hat_jj))`` (eq. 58),
    ``Q^f = diag( (H Gamma)^{-1} Q_tilde (H Gamma)^{-T} dt^2 )`` (eq. 57, main diagonal).

    Parameters
    ----------
    gamma2 : (N, m) squared innovations of the window (diag of gamma gamma^T)
    H : (m, n) output Jacobian, square here (eq. 57 inverts it)
    Gam : (n, b) discrete fault/noise input matrix, square here
    Q, R : input and measurement noise covariances
    dt_s : sample interval (s)

    The numpy path's form of these equations; the kernel's ``update`` computes them with
    sequential sums and a Gauss-Jordan inverse (module docstring: why both stay).
    """
    Cr = gamma2.sum(axis=0) / gamma2.shape[0]
    HG = H @ Gam
    q_hat = Cr - ((HG @ Q) * HG).sum(axis=1) / dt_s - R.diagonal()  # eq. 53 (diagonal)
    q_tilde = np.maximum(q_hat, 0.0)  # eq. 58
    A, ok = solve_general(HG, eye(HG.shape[0]))  # (H Gamma)^{-1}, general LU solve
    if not ok:
        return np.zeros((Gam.shape[1], Gam.shape[1]))
    return np.diag((A * A) @ q_tilde * (dt_s * dt_s))  # eq. 57, main diagonal


class PackedTwoStage:
    """Compiled non-iterated steps for an identity output ``h(x) = x`` on a packed state.

    The estimator hot path (:class:`~gcs_monitor.families.imu.imu_ts.ImuTwoStageEstimator` on the
    GS-KM): the model supplies ``F``, ``G`` and the propagated ``x_bar``; one kernel call
    (``_two_stage_jit.step_identity_output``) runs exactly the calls of :func:`_step_compiled`
    (``hx = x_pred``, ``H = I``) on one contiguous buffer per state instead of a dozen boxed
    arrays. Each step returns a new :class:`TwoStageState` whose arrays are views of a new buffer
    (states stay immutable); a state that did not come from here is packed first.
    tests/gcs_monitor/filters/test_two_stage.py checks it against :func:`two_stage_step`.
    """

    BLOCK = 64  # states per allocation (see :meth:`step`)

    def __init__(self, n: int, b: int, m: int, window_n: int) -> None:
        self.n, self.b, self.m, self.window_n = n, b, m, window_n
        sizes = (n, n * n, b, b * b, n * b, b * b, n, n * n, window_n * m)
        self.size = sum(sizes)
        self._last: tuple[TwoStageState | None, np.ndarray] = (None, np.empty(0))
        self._kern = load_kernels("gcs_monitor.filters._two_stage_jit")
        self._next = self.BLOCK  # next unused row of the current block (none yet)
        self._rows: tuple[np.ndarray, ...] = ()

    def pack(self, s: TwoStageState) -> np.ndarray:
        """The packed buffer of ``s`` (x_bar, P_bar, f, Pf, V, Qf, x, Px, gamma2 flattened)."""
        return np.concatenate([np.ravel(a) for a in (s.x_bar, s.P_bar, s.f, s.Pf, s.V, s.Qf,
                                                     s.x, s.Px, s.gamma2)])

    def _split(self, buf: np.ndarray) -> tuple[np.ndarray, ...]:
        """The components of packed buffers ``buf`` (..., size) as views (..., shape), in the
        order of :meth:`pack`."""
        n, b, m, w = self.n, self.b, self.m, self.window_n
        lead = buf.shape[:-1]
        shapes = ((n,), (n, n), (b,), (b, b), (n, b), (b, b), (n,), (n, n), (w, m))
        out = []
        o = 0
        for shape in shapes:
            size = math.prod(shape)
            out.append(buf[..., o:o + size].reshape(lead + shape))
            o += size
        return tuple(out)

    def view(self, buf: np.ndarray, k: int) -> TwoStageState:
        """A :class:`TwoStageState` whose arrays are views of ``buf``."""
        x_bar, P_bar, f, Pf, V, Qf, x, Px, gamma2 = self._split(buf)
        return TwoStageState(x_bar=x_bar, P_bar=P_bar, f=f, Pf=Pf, V=V, Qf=Qf, x=x, Px=Px, k=k,
                             gamma2=gamma2)

    def _new_block(self) -> None:
        """Buffers for the next :attr:`BLOCK` steps: a (BLOCK, size) state block and a
        (BLOCK, 3 m) innovation block, with every component as a (BLOCK, ...) view, so that a
        step's new state and innovation are rows of them (integer indexing: one view each)."""
        m = self.m
        states = np.empty((self.BLOCK, self.size))
        innov = np.empty((self.BLOCK, 3 * m))
        self._rows = (states, innov, *self._split(states),
                      innov[:, :m], innov[:, m:2 * m], innov[:, 2 * m:])
        self._next = 0

    def step(self, s: TwoStageState, F: Mat, G: Mat, xb_prop: Vec, y: Vec, dt_s: float,
             noise: TwoStageNoise, cfg: TwoStageConfig) -> tuple[TwoStageState, Innovation]:
        """:func:`two_stage_step` for ``h(x) = x`` after the iterated steps (``s.k >= n_it``).

        Parameters
        ----------
        F, G : (n, n), (n, b) model Jacobians at ``(s.x, u_prev - s.f)`` (Lu2016 note 1)
        xb_prop : (n,) ``model.propagate(s.x_bar, u_prev, u_now, dt_s)`` (eq. 31 without ubar)

        Every step writes a row of its own (states stay immutable); rows come in blocks of
        :attr:`BLOCK` (:meth:`_new_block`).
        """
        return self.step_with(self._kern.step_identity_output, (F, G, xb_prop), s, y, dt_s,
                              noise, cfg)

    def step_with(self, kernel: Callable[..., int], model_args: tuple[object, ...],
                  s: TwoStageState, y: Vec, dt_s: float, noise: TwoStageNoise,
                  cfg: TwoStageConfig) -> tuple[TwoStageState, Innovation]:
        """:meth:`step` through ``kernel(buf, k, new_buf, *model_args, y, Q, R, adapt, dt_s,
        gate_sigma, window_n, out)``: ``step_identity_output`` with ``model_args = (F, G,
        xb_prop)``, or a model's kernel that computes those from the packed state and its own
        ``model_args`` and then calls it (``families/imu/_imu_ts_jit.py``), one dispatch."""
        assert s.k >= cfg.n_iterated_steps
        last, buf = self._last
        if last is not s:
            buf = self.pack(s)
        i = self._next
        if i == self.BLOCK:
            self._new_block()
            i = 0
        self._next = i + 1
        (states, innovs, x_bar, P_bar, f, Pf, V, Qf, x, Px, gamma2, nu, S_diag,
         test_ratio) = self._rows
        new_buf = states[i]
        m = self.m
        code = kernel(buf, s.k, new_buf, *model_args, y, noise.Q, noise.R, cfg.adapt, dt_s,
                      cfg.gate_sigma, self.window_n, innovs[i])
        if code == 1:  # prediction failed (P^f not PD): as _step_compiled
            return _fail(s, np.full(m, np.nan), np.full((m, m), np.nan), cfg.gate_sigma)
        innov = Innovation(nu=nu[i], S_diag=S_diag[i], test_ratio=test_ratio[i],
                           numerics_ok=code == 0)
        if code != 0:
            return s, innov
        new = TwoStageState(x_bar=x_bar[i], P_bar=P_bar[i], f=f[i], Pf=Pf[i], V=V[i], Qf=Qf[i],
                            x=x[i], Px=Px[i], k=s.k + 1, gamma2=gamma2[i])
        self._last = (new, new_buf)
        return new, innov
