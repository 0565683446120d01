"""Longitudinal air-data model with wind states (Wan2018 sec. II-A, eqs. 1-16, 20).

State ``x = [alpha, V_g, W_x, W_z]`` (rad, m/s, m/s, m/s); unknown input
``u = [u_alpha, u_v, u_wx, u_wz]`` (rad/s, m/s^2, m/s^2, m/s^2); measured parameters
``Theta = [V_g, theta, q, A_x, A_z, z]`` (m/s, rad, rad/s, m/s^2, m/s^2, m); outputs
``y = [V_g, V_z, alpha, V_c]`` (m/s, m/s, rad, m/s).

Sign conventions (chosen to be physically consistent, see docs/papers-notes.md "Wan2018"):

* ``A_x, A_z`` are the body-axis specific forces (FRD, so ``A_z ~ -g`` in level flight);
  this is what eqs. 5-6 need (``R_BI [0, g]`` adds gravity).
* ``W_x, W_z`` are the inertial wind components along local north-ish horizontal (projected on
  the aircraft's vertical plane) and *down*: this is the frame of eqs. 5-10 (gravity
  ``[0, 0, g]`` is down there and the wind triangle uses ``R_BI``).
* ``V_z`` is the vertical speed *positive up*. Wan2018 eq. 15 prints
  ``V_z = -V_t sin(alpha - theta) + W_z``, which mixes an up-positive kinematic term with the
  down-positive wind of eqs. 5-10; we implement ``V_z = -V_g sin(alpha - theta) - W_z``.

``V_g`` appears both as a state and as a measured parameter (Wan2018 Remark 1): the state
dynamics and the V_z / V_c outputs use the measured ``Theta[0]``, so ``a_12 = c_22 = 0``.

The outputs, the Jacobians and the CAS relation run in the numba kernels of
``models/_airdata_jit.py`` (the functions below wrap them), which the MHE's compiled
linearisation over the horizon (``AirDataModel.linearise_horizon``) calls too. The transition
:func:`airdata_f` is plain Python; the kernel's horizon defects carry their own form of it,
with the eq. 8 term rounded differently (module docstring there: why both stay). The reference
of the equivalence test is ``tests/reference/airdata.py``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from gcs_monitor.core import constants as c
from gcs_monitor.core.atmosphere import tas_from_cas
from gcs_monitor.core.kernels import load_kernels
from gcs_monitor.core.params import param
from gcs_monitor.core.types import Mat, Vec

N_X = 4  # [alpha, V_g, W_x, W_z]
N_U = 4  # [u_alpha, u_v, u_wx, u_wz]
N_Y = 4  # [V_g, V_z, alpha, V_c]
N_THETA = 6  # [V_g, theta, q, A_x, A_z, z]; 8 with the lateral terms: + [phi, beta]

# Indices into the state, output and parameter vectors.
IX_AOA, IX_VG, IX_WX, IX_WZ = 0, 1, 2, 3
IY_VG, IY_VZ, IY_AOA, IY_CAS = 0, 1, 2, 3
IT_VG, IT_THETA, IT_Q, IT_AX, IT_AZ, IT_Z = 0, 1, 2, 3, 4, 5
IT_PHI, IT_BETA = 6, 7  # optional (ours): bank and sideslip, see :func:`lateral`


def lateral(theta_p: Vec | Sequence[float]) -> tuple[float, float]:
    """(phi, beta) of an 8-entry Theta, (0, 0) for Wan2018's 6-entry one.

    Wan2018's eqs. 12-15 are the wings-level, zero-sideslip forms of the exact longitudinal
    relations (ours, not in the paper; docs/papers-notes.md "lateral terms"):

    * gravity along the body normal and along the velocity: ``g cos(alpha - theta)`` and
      ``g sin(alpha - theta)`` are ``g (cos a cos th cos phi + sin a sin th)`` and
      ``g (sin a cos th cos phi - cos a sin th)``;
    * the flight-path angle of eq. 15: ``sin(theta - alpha)`` is ``sin(gamma) = cos a cos b
      sin th - (sin phi sin b + cos phi sin a cos b) cos th``.

    With phi = beta = 0 both reduce to the paper's terms exactly.
    """
    if len(theta_p) > IT_BETA:
        return float(theta_p[IT_PHI]), float(theta_p[IT_BETA])
    return 0.0, 0.0


def _gravity_terms(alpha: float, theta: float, phi: float) -> tuple[float, float]:
    """(g_alpha, g_v) per unit g (see :func:`lateral`): ``cos(alpha - theta)`` and
    ``sin(alpha - theta)`` at phi = 0."""
    sa, ca = math.sin(alpha), math.cos(alpha)
    st, ct, cp = math.sin(theta), math.cos(theta), math.cos(phi)
    return ca * ct * cp + sa * st, sa * ct * cp - ca * st

# Wan2018 eq. 16: 5 gamma R, the factor of T and T0 in the pitot-static relation.
_K_CAS = 5.0 * c.ISA_GAMMA * c.ISA_R_JPKGK
_SQRT_K_T0 = math.sqrt(_K_CAS * c.ISA_T0_K)
_EXP_ISENTROPIC = 3.5  # gamma / (gamma - 1) for gamma = 1.4 (Wan2018 eq. 16)
_GAS_EXP = -c.GRAVITY_STD_MPS2 / (c.ISA_R_JPKGK * c.ISA_LAPSE_KPM)


@dataclass(frozen=True, slots=True)
class AirDataModelParams:
    """Constants of the Wan2018 longitudinal model.

    ``g_mps2`` is the gravity of eqs. 5-9; Wan2018 does not give a value, we use standard
    gravity (the altitude dependence is far below the model's approximation errors).

    ``wind_accel_in_alpha`` keeps the wind-acceleration term of eq. 8,
    ``f_w,alpha / V_t = (W_x_dot sin(alpha - theta) - W_z_dot cos(alpha - theta)) / V_t``, with
    the wind acceleration taken from the unknown wind input u_w of eq. 1 (and V_t ~ V_g as in
    eq. 13). Wan2018 eq. 12 drops it ("V_t >> f_w,alpha"); for its winds (accelerations below
    15 kts/s) the term is below 0.04 rad/s, but Dryden turbulence sampled at 20 Hz changes the
    wind by 10-30 m/s^2 from sample to sample, so a vertical gust moves alpha by W_z_dot / V
    ~ 5 deg/s that eq. 13 attributes to nothing (the fault-free AoA residual then lags every
    gust; see docs/papers-notes.md "Wan2018"). With the term, u_wz moves alpha and W_z together
    and leaves V_z unchanged, as a gust does. False gives eq. 13 exactly.
    """

    g_mps2: float = c.GRAVITY_STD_MPS2
    wind_accel_in_alpha: bool = True


def cas_from_tas_with_derivative(tas_mps: float, alt_m: float) -> tuple[float, float]:
    """Calibrated airspeed and dV_c/dV_t (Wan2018 eq. 16), ISA temperature at ``alt_m``.

    Same formula as :func:`gcs_monitor.core.atmosphere.cas_from_tas`, with its analytic
    derivative for the output Jacobian (row 4 of C, Wan2018 eq. 23). The kernel
    ``models/_airdata_jit.cas_and_derivative`` computes it.
    """
    kern = load_kernels("gcs_monitor.models._airdata_jit")
    cas, dcas = kern.cas_and_derivative(float(tas_mps), float(alt_m), _JIT_CONSTS)
    return float(cas), float(dcas)


def airdata_derivative(x: Vec, theta_p: Vec, p: AirDataModelParams) -> Vec:
    """Continuous-time right-hand side without unknown inputs (Wan2018 eqs. 13-14, 1).

    Parameters
    ----------
    x : (4,) [alpha rad, V_g m/s, W_x m/s, W_z m/s (down)]
    theta_p : (6,) Theta = [V_g m/s, theta rad, q rad/s, A_x m/s^2, A_z m/s^2, z m]
    p : model constants

    Returns
    -------
    (4,) [alpha_dot, V_g_dot, 0, 0]
    """
    th = theta_p.tolist()
    alpha_dot, vg_dot = _derivative(float(x[IX_AOA]), th, p.g_mps2)
    return np.array([alpha_dot, vg_dot, 0.0, 0.0])


def _derivative(alpha: float, th: list[float], g_mps2: float) -> tuple[float, float]:
    """(alpha_dot, V_g_dot) of :func:`airdata_derivative` on Python floats (``th``: Theta as a
    list; a 4-vector's numpy operations cost more than its arithmetic)."""
    vg, theta, q, ax, az = th[IT_VG], th[IT_THETA], th[IT_Q], th[IT_AX], th[IT_AZ]
    sa, ca = math.sin(alpha), math.cos(alpha)
    g_a, g_v = _gravity_terms(alpha, theta, lateral(th)[0])
    f_alpha = -ax * sa + az * ca + g_mps2 * g_a  # g cos(alpha - theta) at phi = 0
    f_v = ax * ca + az * sa + g_mps2 * g_v  # g sin(alpha - theta) at phi = 0
    return _div(f_alpha, vg) + q, f_v


def _div(a: float, b: float) -> float:
    """a / b as numpy divides float64 (inf or NaN with a warning for b = 0, where a Python float
    division raises)."""
    return a / b if b != 0.0 else float(np.float64(a) / b)


def airdata_f(x: Vec, u: Vec, theta_p: Vec, dt_s: float, p: AirDataModelParams) -> Vec:
    """Discrete transition x_{k+1} = x_k + t_s (F(x_k, Theta_k) + u_k) (Wan2018 eq. 20a-c),
    plus ``t_s f_w,alpha(u_w) / V_g`` in alpha when ``p.wind_accel_in_alpha`` (eq. 8).

    Parameters
    ----------
    x : (4,) state; u : (4,) unknown inputs (rates); theta_p : (6,) Theta_k; dt_s : t_s (s)
    """
    # Python floats, each entry rounded as the vector form x + t_s (F + u) rounds it
    x0, x1, x2, x3 = x.tolist()
    u0, u1, u2, u3 = u.tolist()
    th = theta_p.tolist()
    dt = float(dt_s)
    alpha_dot, vg_dot = _derivative(x0, th, p.g_mps2)
    a = x0 + dt * (alpha_dot + u0)
    if p.wind_accel_in_alpha:
        d = x0 - th[IT_THETA]
        a += _div(dt * (u2 * math.sin(d) - u3 * math.cos(d)), th[IT_VG])
    return np.array([a, x1 + dt * (vg_dot + u1), x2 + dt * (0.0 + u2), x3 + dt * (0.0 + u3)])


def airdata_f_jac_x(
    x: Vec, theta_p: Vec, dt_s: float, p: AirDataModelParams, u: Vec | None = None
) -> Mat:
    """A_k = dF/dx of :func:`airdata_f` (Wan2018 eq. 23 with a_12 = 0, Remark 1); with the
    eq. 8 term's entry when ``p.wind_accel_in_alpha`` and ``u`` is given."""
    a = np.empty((N_X, N_X))
    k_wacc = 1.0 if p.wind_accel_in_alpha and u is not None else 0.0
    load_kernels("gcs_monitor.models._airdata_jit").transition_jacobian(
        _f64(x), _f64(np.zeros(N_U) if u is None else u), _f64(theta_p), float(dt_s),
        float(p.g_mps2), k_wacc, a)
    return a


def airdata_f_jac_u(
    dt_s: float, x: Vec | None = None, theta_p: Vec | None = None,
    p: AirDataModelParams | None = None,
) -> Mat:
    """B_k = dF/du = t_s I (Wan2018 eq. 20), plus the u_w column entries of the eq. 8 term in
    the alpha row when ``p.wind_accel_in_alpha`` (``x``, ``theta_p`` and ``p`` given)."""
    b = np.empty((N_X, N_U))
    wacc = p is not None and p.wind_accel_in_alpha and x is not None and theta_p is not None
    load_kernels("gcs_monitor.models._airdata_jit").input_matrix(
        _f64(np.zeros(N_X) if x is None else x),
        _f64(np.zeros(N_THETA) if theta_p is None else theta_p), float(dt_s),
        1.0 if wacc else 0.0, b)
    return b


def airdata_h(x: Vec, theta_p: Vec) -> Vec:
    """Outputs y = [V_g, V_z (up), alpha, V_c] (Wan2018 eqs. 1, 11, 15, 16).

    V_z is positive up and W_z positive down, see the module docstring.
    """
    return _outputs(x, theta_p)[0]


def airdata_h_jac_x(x: Vec, theta_p: Vec) -> Mat:
    """C_k = dh/dx (Wan2018 eq. 23 with c_22 = 0, Remark 1)."""
    return _outputs(x, theta_p)[1]


def _outputs(x: Vec, theta_p: Vec) -> tuple[Vec, Mat]:
    h, cm = np.empty(N_Y), np.empty((N_Y, N_X))
    load_kernels("gcs_monitor.models._airdata_jit").outputs(
        _f64(x), _f64(theta_p), _JIT_CONSTS, h, cm)
    return h, cm


def _f64(a: Vec) -> Vec:
    return np.asarray(a, dtype=np.float64)


def airdata_initial_state(
    aoa_rad: float, cas_mps: float, theta_p: Vec, *, wind_z_mps: float = 0.0
) -> Vec:
    """A first state from one set of measurements: invert eq. 11 for W_x with W_z given.

    Uses the exact inverse of eq. 16 for V_t.
    """
    d = aoa_rad - theta_p[IT_THETA]
    tas = tas_from_cas(cas_mps, float(theta_p[IT_Z]))
    wx = (theta_p[IT_VG] - tas - wind_z_mps * math.sin(d)) / math.cos(d)
    return np.array([aoa_rad, theta_p[IT_VG], wx, wind_z_mps])


@dataclass(frozen=True, slots=True)
class AirDataModel:
    """The Wan2018 model bundled for the model-agnostic filters (``filters.mhe``, EKF).

    Method signatures follow :class:`gcs_monitor.filters.mhe.MheModel`.
    """

    params: AirDataModelParams = AirDataModelParams()
    n_x: int = N_X
    n_u: int = N_U
    n_y: int = N_Y

    def f(self, x: Vec, u: Vec, theta_p: Vec, dt_s: float) -> Vec:
        return airdata_f(x, u, theta_p, dt_s, self.params)

    def f_jac_x(self, x: Vec, u: Vec, theta_p: Vec, dt_s: float) -> Mat:
        return airdata_f_jac_x(x, theta_p, dt_s, self.params, u)

    def f_jac_u(self, x: Vec, u: Vec, theta_p: Vec, dt_s: float) -> Mat:
        return airdata_f_jac_u(dt_s, x, theta_p, self.params)

    def h(self, x: Vec, theta_p: Vec) -> Vec:
        return airdata_h(x, theta_p)

    def h_jac_x(self, x: Vec, theta_p: Vec) -> Mat:
        return airdata_h_jac_x(x, theta_p)

    def linearise_horizon(
        self,
        n: int,
        x_lin: Mat,
        u_lin: Mat,
        th: Mat,
        dts: Vec,
        ym: Mat,
        mk: Mat,
        a: Mat,
        b: Mat,
        f: Mat,
        cm: Mat,
        ry: Mat,
    ) -> bool:
        """Compiled linearisation over the first ``n`` horizon nodes (Wan2018 eq. 42).

        Optional part of :class:`gcs_monitor.filters.mhe.MheModel`: fills ``a, b, f`` (nodes
        0..n-2) and the masked ``cm, ry`` (nodes 0..n-1) as ``f_jac_x``, ``f_jac_u``, ``f``,
        ``h_jac_x`` and ``h`` would (the defects with the kernel's form of eq. 20, see the
        module docstring), in one numba call. Returns True.
        """
        load_kernels("gcs_monitor.models._airdata_jit").linearise_horizon(
            n, x_lin, u_lin, th, dts, ym, mk, self.params.g_mps2,
            1.0 if self.params.wind_accel_in_alpha else 0.0, _JIT_CONSTS, a, b, f, cm, ry,
        )  # fmt: skip
        return True


# Constants of eq. 16 for the compiled model, passed as an argument (not read as numba globals,
# which numba's cache would freeze): K, sqrt(K T0), T0, lapse rate, g / (R L) exponent, 3.5.
_JIT_CONSTS = (
    _K_CAS,
    _SQRT_K_T0,
    c.ISA_T0_K,
    c.ISA_LAPSE_KPM,
    _GAS_EXP,
    _EXP_ISENTROPIC,
)


# ------------------------------------------------------------------------------------------------
# Wind bounds of the CMHE from a declared weather envelope (Wan2018 eq. 21b, secs. IV and VI-A)
# ------------------------------------------------------------------------------------------------

# MIL-F-8785C / Lu2016 sec. 2.2.1 Dryden scale length used when an envelope does not give one.
DRYDEN_SCALE_M = 530.0


@dataclass(frozen=True, slots=True)
class WindEnvelope:
    """The weather a flight is declared to meet (a forecast, not measured wind), SI units.

    Wan2018 sec. IV and VI-A: the bounds of eq. 21b "can be time varying to account for
    different weather or flight conditions" and "need to be properly selected according to the
    weather and flight conditions"; the paper does not say how. :func:`envelope_bounds` turns
    this declaration into the box of eq. 21b. The model margins keep the box open (the
    barrier of eq. 44 needs a non-empty interior; u_alpha, u_v, n of eq. 1 "account for ... model
    mismatches").
    """

    wind_mps: float = param(18.0, "steady horizontal wind speed (any direction)", unit="kts")
    wind_z_mps: float = param(3.0, "steady vertical wind speed", unit="kts")
    shear_mps: float = param(0.0, "largest horizontal change of the wind by shear", unit="kts")
    shear_z_mps: float = param(0.0, "largest vertical change of the wind by shear", unit="kts")
    shear_rate_mps2: float = param(1.5, "largest wind acceleration of the shear (both axes)",
                                   unit="kts")
    turbulence_sigma_mps: float = param(0.0, "Dryden intensity sigma_u = sigma_v = sigma_w "
                                        "(0: no turbulence)", unit="kts")
    turbulence_scale_m: float = param(DRYDEN_SCALE_M, "Dryden scale length L", positive=True)
    n_sigma: float = param(3.0, "standard deviations of the turbulence the box holds")
    flight_path_max_rad: float = param(10.0 * math.pi / 180.0, "largest |alpha - theta| "
                                       "(flight-path angle) of the flight; sizes the eq. 15 "
                                       "approximation error that W_z absorbs")
    model_margin_mps: float = param(2.0, "floor of the wind box for the model mismatch the "
                                    "wind states absorb in calm air", unit="kts")
    model_rate_margin_mps2: float = param(0.5, "floor of the wind-rate box for the model "
                                          "mismatch", unit="kts")


@dataclass(frozen=True, slots=True)
class WindBounds:
    """Symmetric box of eq. 21b on W_x, W_z (m/s) and u_wx, u_wz (m/s^2)."""

    wind_x_max_mps: float
    wind_z_max_mps: float
    rate_x_max_mps2: float
    rate_z_max_mps2: float


def envelope_bounds(
    env: WindEnvelope,
    tas_mps: float,
    dt_s: float,
    roll_rad: float,
    g_mps2: float = c.GRAVITY_STD_MPS2,
) -> WindBounds:
    """Bounds of eq. 21b for the current flight condition from a declared envelope.

    Our construction (Wan2018 gives none), each term a bound on one physical source:

    * ``|W_x| <= wind + shear + n sigma`` and ``|W_z| <= wind_z + shear_z + n sigma``: steady
      wind, shear and turbulence add; a Dryden gust stays within ``n sigma`` (Gaussian);
    * ``|u_w|`` is the wind change per sample over ``t_s`` (eq. 20c). A Dryden longitudinal gust
      is a first-order Markov process with ``tau = L / V`` (Lu2016 eq. 21), so its change over
      one sample has the standard deviation ``sigma sqrt(2 (1 - exp(-t_s / tau)))``; ``n`` of
      those divided by ``t_s`` bound the turbulent part of ``u_w`` (the lateral/vertical
      gusts are smoother, so the same value bounds ``u_wz``);
    * the states also absorb the model's approximation errors, which the box must hold too:
      eq. 11 drops ``W_perp^2 / (2 V_g)`` (W_x) and eq. 15 replaces V_t by V_g, an error of
      ``(V_t - V_g) sin(alpha - theta)`` <= ``W_x,max sin(gamma_max)`` (W_z);
    * the shear's own acceleration adds to both axes;
    * W_x is the wind along the heading: in a turn at bank ``phi`` the heading rate
      ``g tan(phi) / V`` turns the horizontal wind into the heading at up to
      ``W_h g |tan phi| / V`` (the longitudinal model of eq. 6 has no heading; this term keeps
      the box valid in the turns the campaign flies).

    Parameters
    ----------
    env : declared envelope
    tas_mps : airspeed for the Dryden time constant (the measured V_g of Theta is used: only
        tau depends on it)
    dt_s : air-data sample interval t_s
    roll_rad : measured bank angle
    """
    v = max(tas_mps, 1.0)
    gust = env.n_sigma * env.turbulence_sigma_mps
    wh = env.wind_mps + env.shear_mps + gust
    wx = wh + wh * wh / (2.0 * v) + env.model_margin_mps  # eq. 11 error
    wz = (env.wind_z_mps + env.shear_z_mps + gust + wh * math.sin(env.flight_path_max_rad)
          + env.model_margin_mps)
    turb_rate = 0.0
    if env.turbulence_sigma_mps > 0.0 and dt_s > 0.0:
        tau = env.turbulence_scale_m / v
        step_sd = env.turbulence_sigma_mps * math.sqrt(2.0 * (1.0 - math.exp(-dt_s / tau)))
        turb_rate = env.n_sigma * step_sd / dt_s
    turn_rate = wx * g_mps2 * abs(math.tan(max(min(roll_rad, 1.4), -1.4))) / v
    rate = env.shear_rate_mps2 + turb_rate + env.model_rate_margin_mps2
    return WindBounds(wx, wz, rate + turn_rate, rate)
