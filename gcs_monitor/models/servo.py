"""Hydraulic servo actuator with its NDI position loop and third-order reference model (Lu2017).

State ``x = [q, q_dot, dP/P_s]`` (rod position m, rod velocity m/s, normalised pressure
difference), input ``u`` = normalised valve command in [-1, 1] (Lu2017 eqs. 1-6).

Note on the relative degree (Lu2017 eq. 12 states r = 2): with ``y = x1`` the valve input
first appears in the *third* derivative of y (``y' = x2``, ``y'' = (A_p P_s x3 - B x2 + F_d)/M``,
``y''' = ... + (A_p P_s / M) g3(x) u``), so ``L_g L_f h = 0`` and the relative degree is 3.
The NDI law (eq. 13) is therefore implemented with r = 3, which is also why the paper's
third-order reference model is the natural companion: it supplies ``q_ref``, its first two
derivatives and ``q_ref'''`` for the error dynamics.

The functions above :func:`pack_params` take and return plain floats (the paper's equations in
their printed form; the simulator's servo bank runs them as its own kernel). The monitor's
closed-loop model -- the plant driven by the NDI law on the model's own states, the input
fault added to the saturated valve command -- runs in the numba kernel of
``models/_servo_jit.py``: :func:`closed_loop_derivative`, :func:`closed_loop_jacobian` and
:func:`propagate` below wrap it (the filters of the servo tier call it directly); its
plain-float reference is ``tests/reference/servo_model.py``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gcs_monitor.core.kernels import load_kernels
from gcs_monitor.core.params import param
from gcs_monitor.core.types import Mat, Vec


@dataclass(frozen=True, slots=True)
class ServoParams:
    """Generic hydraulic actuator parameters (Lu2017 sec. II.A, text below eq. 6)."""

    piston_area_m2: float = param(0.0025, "piston area A_p (Lu2017 sec. II.A)", positive=True)
    damping_nspm: float = param(52.3, "damping coefficient B (Lu2017 sec. II.A)",
                                positive=True)
    supply_pressure_pa: float = param(1.4e7, "reservoir oil pressure P_s (Lu2017 sec. II.A)",
                                      positive=True)
    max_valve_flow_m3ps: float = param(0.0025, "maximum valve flow phi_n (Lu2017 sec. II.A)",
                                       positive=True)
    mean_chamber_volume_m3: float = param(0.001973, "mean actuator chamber volume V_m (Lu2017 "
                                          "sec. II.A)", positive=True)
    bulk_modulus_pa: float = param(1.0e9, "oil bulk modulus E (Lu2017 sec. II.A)",
                                   positive=True)
    moving_mass_kg: float = param(2000.0, "mass of the moving system M (Lu2017 sec. II.A)",
                                  positive=True)
    leakage_mps: float = param(0.023, "normalised leakage parameter L (Lu2017 sec. II.A)",
                               positive=True)


@dataclass(frozen=True, slots=True)
class ServoLoopParams:
    """NDI servo loop and reference model design (ours; Lu2017 gives only the structure).

    The reference model is the third-order low-pass ``w^3 / ((s + w)(s^2 + 2 zeta w s + w^2))``
    (Lu2017 sec. III.B item 1). The NDI linear controller ``nu`` (eq. 13) places the three
    tracking-error poles at ``-ndi_pole_radps``.
    """

    ref_bandwidth_radps: float = param(20.0, "reference model bandwidth w (ours; Lu2017 sec. "
                                       "III.B gives a third-order low-pass)", unit="si",
                                       positive=True)
    ref_damping: float = param(0.8, "reference model damping zeta (ours)", positive=True)
    ndi_pole_radps: float = param(40.0, "triple pole of the NDI tracking-error dynamics "
                                  "(ours; Lu2017 eq. 13 leaves nu to the designer)", unit="si",
                                  positive=True)
    max_valve_cmd: float = param(1.0, "|u| limit of the valve command: phi_n is the maximum "
                                 "valve flow", positive=True)


def chamber_gain(x1_m: float, p: ServoParams) -> float:
    """``2 A_p E V_m / (P_s (V_m^2 - A_p^2 x1^2))`` (1/m), the factor of Lu2017 eq. 4 row 3."""
    a = p.piston_area_m2
    vm = p.mean_chamber_volume_m3
    return (
        2.0 * a * p.bulk_modulus_pa * vm / (p.supply_pressure_pa * (vm * vm - a * a * x1_m * x1_m))
    )


def servo_derivative(
    x1_m: float,
    x2_mps: float,
    x3: float,
    u: float,
    p: ServoParams,
    *,
    f_in: float = 0.0,
    f_ext_n: float = 0.0,
) -> tuple[float, float, float]:
    """Continuous-time hydraulic actuator dynamics (Lu2017 eq. 4).

    Parameters
    ----------
    x1_m, x2_mps, x3 : rod position (m), rod velocity (m/s), dP/P_s (-)
    u : valve command (-), normally in [-1, 1]
    f_in : input fault added to u (Lu2017 eq. 4, ``u + f^i``)
    f_ext_n : external force on the rod F_d (N), e.g. hinge moment / lever arm

    Returns
    -------
    (x1_dot, x2_dot, x3_dot)
    """
    a = p.piston_area_m2
    x2_dot = (a * p.supply_pressure_pa * x3 - p.damping_nspm * x2_mps + f_ext_n) / p.moving_mass_kg
    sgn = 1.0 if u >= 0.0 else -1.0
    flow = (p.max_valve_flow_m3ps / a) * math.sqrt(max(0.0, 1.0 - sgn * x3)) * (u + f_in)
    x3_dot = chamber_gain(x1_m, p) * (flow - p.leakage_mps * x3 - x2_mps)
    return x2_mps, x2_dot, x3_dot


def servo_output(x1_m: float, f_out_m: float = 0.0) -> float:
    """Rod position sensor output ``y = x1 + f^o`` (Lu2017 eq. 5)."""
    return x1_m + f_out_m


def ndi_control(
    y_m: float,
    x2_mps: float,
    x3: float,
    ref: tuple[float, float, float, float],
    p: ServoParams,
    lp: ServoLoopParams,
    *,
    f_ext_n: float = 0.0,
) -> float:
    """NDI valve command (Lu2017 eqs. 7-13 with relative degree 3, see module note).

    ``u = (nu - L_f^3 h) / (L_g L_f^2 h)``,
    ``nu = r''' + k2 (r'' - y'') + k1 (r' - y') + k0 (r - y)``
    with ``(s + lambda)^3`` error dynamics. ``sign(u)`` in g(x) (eq. 11) equals
    ``sign(nu - L_f^3 h)`` because ``L_g L_f^2 h > 0``.

    Parameters
    ----------
    y_m : measured rod position (m) (x1 + f^o: a liquid jam biases it)
    x2_mps, x3 : rod velocity (m/s), dP/P_s (-)
    ref : (r, r', r'', r''') from :func:`reference_model_derivative` states (m, m/s, m/s^2, m/s^3)

    Returns
    -------
    u : valve command, saturated to ``+-lp.max_valve_cmd``
    """
    a = p.piston_area_m2
    m = p.moving_mass_kg
    c = chamber_gain(y_m, p)
    ydd = (a * p.supply_pressure_pa * x3 - p.damping_nspm * x2_mps + f_ext_n) / m
    lf3h = (
        a * p.supply_pressure_pa * c * (-p.leakage_mps * x3 - x2_mps) - p.damping_nspm * ydd
    ) / m
    lam = lp.ndi_pole_radps
    k2 = 3.0 * lam
    k1 = 3.0 * lam * lam
    k0 = lam * lam * lam
    nu = ref[3] + k2 * (ref[2] - ydd) + k1 * (ref[1] - x2_mps) + k0 * (ref[0] - y_m)
    num = nu - lf3h
    sgn = 1.0 if num >= 0.0 else -1.0
    lglf2h = (
        a
        * p.supply_pressure_pa
        / m
        * c
        * (p.max_valve_flow_m3ps / a)
        * math.sqrt(max(1.0e-6, 1.0 - sgn * x3))
    )
    u = num / lglf2h
    umax = lp.max_valve_cmd
    return umax if u > umax else (-umax if u < -umax else u)


def reference_model_derivative(
    r_m: float, rd_mps: float, rdd_mps2: float, q_com_m: float, lp: ServoLoopParams
) -> tuple[float, float, float]:
    """Third-order reference model (Lu2017 sec. III.B item 1).

    ``r''' = w^3 (q_com - r) - (2 zeta + 1) w^2 r' - (2 zeta + 1) w r''``, i.e. the transfer
    ``w^3 / ((s + w)(s^2 + 2 zeta w s + w^2))``.

    Returns
    -------
    (r', r'', r''') : the state derivative; r''' is also the feed-forward of the NDI law.
    """
    w = lp.ref_bandwidth_radps
    z2 = 2.0 * lp.ref_damping + 1.0
    rddd = w * w * w * (q_com_m - r_m) - z2 * w * w * rd_mps - z2 * w * rdd_mps2
    return rd_mps, rdd_mps2, rddd


def max_rod_rate_mps(p: ServoParams) -> float:
    """Rod velocity with the valve fully open and no load (Lu2017 eq. 4 at steady state).

    With ``u = 1``, ``x2' = 0`` gives ``x3 = B x2 / (A_p P_s)`` and ``x3' = 0`` gives
    ``x2 = (phi_n/A_p) sqrt(1 - x3) - L x3``; solved by fixed-point iteration (x3 << 1).
    """
    v = p.max_valve_flow_m3ps / p.piston_area_m2
    x2 = v
    for _ in range(20):
        x3 = p.damping_nspm * x2 / (p.piston_area_m2 * p.supply_pressure_pa)
        x2 = v * math.sqrt(1.0 - x3) - p.leakage_mps * x3
    return x2


def stalled_pressure(u: float, p: ServoParams) -> float:
    """dP/P_s at which the valve flow balances the leakage with the rod held (x2 = 0).

    Solves ``(phi_n/A_p) sqrt(1 - s x3) u = L x3`` (Lu2017 eq. 4 row 3 with x3' = 0); used at a
    mechanical stop or a jam, where the pressure settles within milliseconds.
    """
    if u == 0.0:
        return 0.0
    s = 1.0 if u > 0.0 else -1.0
    k = (
        p.max_valve_flow_m3ps / p.piston_area_m2 * abs(u) / p.leakage_mps
    )  # sqrt(1 - z) k = z, z = s x3
    # z^2 + k^2 z - k^2 = 0
    z = 0.5 * (-k * k + math.sqrt(k**4 + 4.0 * k * k))
    return s * z


# ---------------------------------------------------------------------------------------------
# the monitor's closed-loop model (kernel: models/_servo_jit.py)
# ---------------------------------------------------------------------------------------------

_KERNEL = "gcs_monitor.models._servo_jit"


def pack_params(p: ServoParams, lp: ServoLoopParams, stroke_m: float) -> np.ndarray:
    """The constants of eqs. 4 and 13, of the reference model and the rod stroke, in the order
    of the kernel's ``P_*`` indices."""
    k = load_kernels(_KERNEL)
    a = p.piston_area_m2
    vm = p.mean_chamber_volume_m3
    w = lp.ref_bandwidth_radps
    z2 = 2.0 * lp.ref_damping + 1.0
    lam = lp.ndi_pole_radps
    out = np.empty(k.N_PARAMS)
    out[k.P_APS] = a * p.supply_pressure_pa
    out[k.P_BB] = p.damping_nspm
    out[k.P_INV_M] = 1.0 / p.moving_mass_kg
    out[k.P_VMAX] = p.max_valve_flow_m3ps / a
    out[k.P_LEAK] = p.leakage_mps
    out[k.P_CNUM] = 2.0 * a * p.bulk_modulus_pa * vm / p.supply_pressure_pa
    out[k.P_VM2] = vm * vm
    out[k.P_A2] = a * a
    out[k.P_W3] = w * w * w
    out[k.P_Z2W2] = z2 * w * w
    out[k.P_Z2W] = z2 * w
    out[k.P_K2] = 3.0 * lam
    out[k.P_K1] = 3.0 * lam * lam
    out[k.P_K0] = lam * lam * lam
    out[k.P_UMAX] = lp.max_valve_cmd
    out[k.P_STROKE] = stroke_m
    return out


def closed_loop_derivative(s: Vec, q_com_m: float, f_in: float, prm: np.ndarray) -> Vec:
    """``ds/dt`` of the closed servo loop (Lu2017 eqs. 4, 13 with r = 3).

    Parameters
    ----------
    s : (6,) [x1 (m), x2 (m/s), x3 (-), r (m), r' (m/s), r'' (m/s^2)]: plant and reference model
    q_com_m : rod command (m), the reference model's input
    f_in : input fault f^i added to the saturated NDI valve command (valve units, -)
    prm : :func:`pack_params`
    """
    d = np.empty(6)
    load_kernels(_KERNEL).deriv(np.asarray(s, dtype=np.float64), float(q_com_m), float(f_in),
                                prm, d)
    return d


def closed_loop_jacobian(s: Vec, q_com_m: float, f_in: float,
                         prm: np.ndarray) -> tuple[Mat, Vec]:
    """``(A, G)``: ``A = ds_dot/ds`` (6, 6) of the closed loop (the NDI law depends on the plant
    and the reference states) and ``G = ds_dot/df^i`` (6,), at the arguments of
    :func:`closed_loop_derivative`."""
    A = np.empty((6, 6))
    G = np.empty(6)
    load_kernels(_KERNEL).jacobian(np.asarray(s, dtype=np.float64), float(q_com_m),
                                   float(f_in), prm, A, G)
    return A, G


@dataclass(frozen=True, slots=True)
class Propagation:
    """One sample interval of the closed loop (:func:`propagate`).

    s : (6,) state at the end; Phi : (6, 6) transition; Gamma : (6,) response of the state to a
    constant input fault over the interval; Qd : (6, 6) discrete process noise (Lu2017 eqs.
    19-20, 39); plant and reference states
    """

    s: Vec
    Phi: Mat
    Gamma: Vec
    Qd: Mat


def propagate(s: Vec, q_com0_m: float, q_com1_m: float, f_in: float, dt_s: float, n_sub: int,
              prm: np.ndarray, *, q_valve: float = 0.0,
              q_state: tuple[float, ...] = (0.0,) * 6, knee_s: float | None = None
              ) -> Propagation:
    """RK4 of the closed loop over ``dt_s`` in ``n_sub`` substeps, the rod command linear from
    ``q_com0_m`` to ``q_com1_m`` until ``knee_s`` into the interval (default: its end) and held
    after it, with Phi, Gamma and Q_d (valve-command noise of PSD
    ``q_valve`` (s), state noises of PSDs ``q_state`` (6,) (SI^2 s)); see the kernel."""
    out = np.array(s, dtype=np.float64)
    Phi = np.empty((6, 6))
    Gam = np.empty(6)
    Qd = np.empty((6, 6))
    knee = float(dt_s) if knee_s is None else float(knee_s)
    load_kernels(_KERNEL).propagate(out, float(q_com0_m), float(q_com1_m), float(f_in),
                                    float(dt_s), knee, int(n_sub), prm, True, float(q_valve),
                                    np.asarray(q_state, dtype=np.float64), Phi, Gam, Qd)
    return Propagation(out, Phi, Gam, Qd)


def command_timing_noise(s: Vec, q_com0_m: float, q_com1_m: float, f_in: float, dt_s: float,
                         n_sub: int, prm: np.ndarray) -> Mat:
    """(6, 6) state covariance of a rod-command change at an unknown instant of the interval
    (the kernel's ``command_timing_noise``)."""
    Q = np.zeros((6, 6))
    load_kernels(_KERNEL).command_timing_noise(np.array(s, dtype=np.float64), float(q_com0_m),
                                               float(q_com1_m), float(f_in), float(dt_s),
                                               int(n_sub), prm, Q)
    return Q
