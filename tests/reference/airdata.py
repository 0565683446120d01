"""Plain-float reference of the air-data model kernels (Wan2018 eqs. 11, 15, 16, 20, 23;
``models/_airdata_jit.py``).

The output function, its Jacobian, the transition Jacobians and the CAS relation as
``gcs_monitor.models.airdata`` computed them in Python before they wrapped the kernels (the
sign conventions and the lateral terms are documented there).
"""

from __future__ import annotations

import math
from typing import cast

import numpy as np

from gcs_monitor.core import constants as c
from gcs_monitor.core.types import Mat, Vec
from gcs_monitor.models.airdata import (
    _EXP_ISENTROPIC,
    _GAS_EXP,
    _K_CAS,
    _SQRT_K_T0,
    IT_AX,
    IT_AZ,
    IT_THETA,
    IT_VG,
    IT_Z,
    IX_AOA,
    IX_VG,
    IX_WX,
    IX_WZ,
    IY_AOA,
    IY_CAS,
    IY_VG,
    IY_VZ,
    N_X,
    N_Y,
    AirDataModelParams,
    lateral,
)


def _gravity_terms(alpha: float, theta: float, phi: float) -> tuple[float, float, float, float]:
    """(g_alpha, g_v, d g_alpha / d alpha, d g_v / d alpha) per unit g (see :func:`lateral`)."""
    sa, ca = math.sin(alpha), math.cos(alpha)
    st, ct, cp = math.sin(theta), math.cos(theta), math.cos(phi)
    return (ca * ct * cp + sa * st, sa * ct * cp - ca * st,
            -sa * ct * cp + ca * st, ca * ct * cp + sa * st)


def _sin_gamma(alpha: float, theta: float, phi: float, beta: float) -> tuple[float, float]:
    """(sin gamma_air, d / d alpha) of the exact flight-path relation (see :func:`lateral`)."""
    sa, ca = math.sin(alpha), math.cos(alpha)
    st, ct = math.sin(theta), math.cos(theta)
    sp, cp = math.sin(phi), math.cos(phi)
    sb, cb = math.sin(beta), math.cos(beta)
    return (ca * cb * st - (sp * sb + cp * sa * cb) * ct,
            -sa * cb * st - cp * ca * cb * ct)


def isa_temp_pbar(alt_m: float) -> tuple[float, float]:
    """ISA temperature (K) and static pressure ratio p/p0 at pressure altitude (Wan2018 eq. 16)."""
    t_k = c.ISA_T0_K + c.ISA_LAPSE_KPM * alt_m
    p_bar = (1.0 + c.ISA_LAPSE_KPM * alt_m / c.ISA_T0_K) ** _GAS_EXP
    return t_k, p_bar


def cas_from_tas_with_derivative(tas_mps: float, alt_m: float) -> tuple[float, float]:
    """Calibrated airspeed and dV_c/dV_t (Wan2018 eq. 16), ISA temperature at ``alt_m``.

    Same formula as :func:`gcs_monitor.core.atmosphere.cas_from_tas`, with its analytic
    derivative for the output Jacobian (row 4 of C, Wan2018 eq. 23).
    """
    t_k, p_bar = isa_temp_pbar(alt_m)
    a = 1.0 + tas_mps * tas_mps / (_K_CAS * t_k)
    a25 = a**2.5
    big_y = (a25 * a - 1.0) * p_bar + 1.0
    y_root = big_y ** (1.0 / _EXP_ISENTROPIC)
    rho = math.sqrt(max(y_root - 1.0, 0.0))
    cas = _SQRT_K_T0 * rho
    if rho <= 0.0:
        return cas, 0.0
    # d/dVt of sqrt(Y^(1/3.5) - 1) = Y^(1/3.5 - 1) * p_bar * a^2.5 * 2 Vt / (k T) / (2 rho)
    dy_root = (y_root / big_y) * p_bar * a25 * 2.0 * tas_mps / (_K_CAS * t_k)
    return cas, _SQRT_K_T0 * dy_root / (2.0 * rho)


def tas_approx(x: Vec, theta_p: Vec) -> float:
    """True airspeed from the wind triangle with V_g >> wind (Wan2018 eq. 11)."""
    d = x[IX_AOA] - theta_p[IT_THETA]
    return cast(float, theta_p[IT_VG] - x[IX_WX] * math.cos(d) - x[IX_WZ] * math.sin(d))


def airdata_f_jac_x(
    x: Vec, theta_p: Vec, dt_s: float, p: AirDataModelParams, u: Vec | None = None
) -> Mat:
    """A_k = dF/dx of :func:`airdata_f` (Wan2018 eq. 23 with a_12 = 0, Remark 1)."""
    alpha = x[IX_AOA]
    vg, theta, ax, az = theta_p[IT_VG], theta_p[IT_THETA], theta_p[IT_AX], theta_p[IT_AZ]
    sa, ca = math.sin(alpha), math.cos(alpha)
    _, _, dg_a, dg_v = _gravity_terms(alpha, theta, lateral(theta_p)[0])
    d_falpha = -ax * ca - az * sa + p.g_mps2 * dg_a
    d_fv = -ax * sa + az * ca + p.g_mps2 * dg_v
    a = np.eye(N_X)
    a[IX_AOA, IX_AOA] += dt_s * d_falpha / vg
    a[IX_VG, IX_AOA] = dt_s * d_fv
    if p.wind_accel_in_alpha and u is not None:
        d = alpha - theta
        a[IX_AOA, IX_AOA] += dt_s * (u[IX_WX] * math.cos(d) + u[IX_WZ] * math.sin(d)) / vg
    return a


def airdata_f_jac_u(
    dt_s: float, x: Vec | None = None, theta_p: Vec | None = None,
    p: AirDataModelParams | None = None,
) -> Mat:
    """B_k = dF/du = t_s I (Wan2018 eq. 20), plus the u_w column entries of the eq. 8 term in
    the alpha row when ``p.wind_accel_in_alpha`` (``x``, ``theta_p`` and ``p`` given)."""
    b = dt_s * np.eye(N_X)
    if p is not None and p.wind_accel_in_alpha and x is not None and theta_p is not None:
        d = x[IX_AOA] - theta_p[IT_THETA]
        b[IX_AOA, IX_WX] = dt_s * math.sin(d) / theta_p[IT_VG]
        b[IX_AOA, IX_WZ] = -dt_s * math.cos(d) / theta_p[IT_VG]
    return b


def airdata_h(x: Vec, theta_p: Vec) -> Vec:
    """Outputs y = [V_g, V_z (up), alpha, V_c] (Wan2018 eqs. 1, 11, 15, 16).

    V_z is positive up and W_z positive down, see the module docstring.
    """
    sg, _ = _sin_gamma(x[IX_AOA], theta_p[IT_THETA], *lateral(theta_p))
    vz_up = theta_p[IT_VG] * sg - x[IX_WZ]  # -V_g sin(alpha - theta) - W_z at phi = beta = 0
    cas, _ = cas_from_tas_with_derivative(tas_approx(x, theta_p), theta_p[IT_Z])
    return np.array([x[IX_VG], vz_up, x[IX_AOA], cas])


def airdata_h_jac_x(x: Vec, theta_p: Vec) -> Mat:
    """C_k = dh/dx (Wan2018 eq. 23 with c_22 = 0, Remark 1)."""
    d = x[IX_AOA] - theta_p[IT_THETA]
    sd, cd = math.sin(d), math.cos(d)
    vg = theta_p[IT_VG]
    _, dcas = cas_from_tas_with_derivative(tas_approx(x, theta_p), theta_p[IT_Z])
    cm = np.zeros((N_Y, N_X))
    cm[IY_VG, IX_VG] = 1.0
    cm[IY_VZ, IX_AOA] = vg * _sin_gamma(x[IX_AOA], theta_p[IT_THETA], *lateral(theta_p))[1]
    cm[IY_VZ, IX_WZ] = -1.0
    cm[IY_AOA, IX_AOA] = 1.0
    # dV_t/dalpha, dV_t/dW_x, dV_t/dW_z of eq. 11
    cm[IY_CAS, IX_AOA] = dcas * (x[IX_WX] * sd - x[IX_WZ] * cd)
    cm[IY_CAS, IX_WX] = -dcas * cd
    cm[IY_CAS, IX_WZ] = -dcas * sd
    return cm
