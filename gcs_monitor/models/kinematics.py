"""Aircraft kinematic models for IMU fault reconstruction (Lu2016 sec. 2.1).

GS-KM: ground-speed kinematic model over a spherical, rotating earth (Lu2016 eqs. 11-14).
    state  x   = [U_N, U_E, U_D, phi, theta, psi]   (m/s NED ground velocity, rad ZYX Euler)
    input  u_m = [A_x, A_y, A_z, p, q, r]           (m/s^2 specific force FRD, rad/s body rates FRD)
    output y   = x                                  (GPS velocity + attitude, Lu2016 eq. 14)
    latitude ``lat_rad`` (delta) and altitude ``alt_m`` (h) are parameters taken from GPS.

AS-KM: airspeed kinematic model (Lu2016 eqs. 15-20), for comparison.
    state  x'  = [u_a, v_a, w_a, phi, theta, psi]   (m/s body FRD airspeed, rad)
    output y'  = [V, alpha, beta, phi, theta, psi]

Faults enter through the input: the model is ``f(x, u_m - f^i)`` (Lu2016 eq. 5), so
``df/df^i = -df/du = G(x)`` (Lu2016 eqs. 13, 19): the same matrix distributes noise and faults.

The GS-KM runs in the numba kernel of ``models/_kinematics_jit.py``: :func:`gs_km_f`, the
Jacobians and :class:`GsKm` below wrap it, and the filter's hot path calls it directly
(``estimators/imu_ts.py``). The plain-float reference that the equivalence test compares it
with, bit for bit, is ``tests/reference/kinematics.py``. The AS-KM (for comparison) is plain
Python, working on floats internally (it runs at 100 Hz inside filters).

Deviation from the printed text (see docs/papers-notes.md, Lu2016): the printed psi_dot row of
eq. 11 has ``+(U_E/(R_e+h) + Omega cos(delta)) tan(theta) cos(psi)``; the rotation of the
navigation frame gives ``-(...)`` (the same sign as in the phi_dot row, since
``psi_dot = sin(theta) * phi_dot`` for a horizontal frame rate). We implement the physically
right sign; ``tests/gcs_monitor/models/test_kinematics.py`` checks it against the DCM kinematics.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gcs_monitor.core.atmosphere import gravity_mps2
from gcs_monitor.core.kernels import load_kernels
from gcs_monitor.core.types import Mat, Vec

N_X = 6  # state dimension of both models
N_U = 6  # IMU input dimension

# ---------------------------------------------------------------------------------------------
# GS-KM
# ---------------------------------------------------------------------------------------------


def _f64(a: Vec) -> Vec:
    return np.asarray(a, dtype=np.float64)


def gs_km_f(x: Vec, u: Vec, lat_rad: float, alt_m: float) -> Vec:
    """GS-KM state derivative ``f(x, u)`` (Lu2016 eq. 11, gravity eq. 12).

    Parameters
    ----------
    x : (6,) [U_N, U_E, U_D (m/s, NED), phi, theta, psi (rad)]
    u : (6,) IMU input [A_x, A_y, A_z (m/s^2, FRD), p, q, r (rad/s, FRD)]; pass ``u_m - f_hat``
        for the fault-corrected model ``f(x, u_m - f^i)``
    lat_rad : geodetic latitude delta (rad)
    alt_m : altitude h above the sphere (m)
    """
    out = np.empty(N_X)
    g = gravity_mps2(lat_rad, alt_m)
    load_kernels("gcs_monitor.models._kinematics_jit").rates(
        _f64(x), _f64(u), float(lat_rad), float(alt_m), g, out)
    return out


def gs_km_jac_x(x: Vec, u: Vec, lat_rad: float, alt_m: float) -> Mat:
    """``df/dx`` of the GS-KM (Lu2016 eq. 34, F), shape (6, 6). Arguments as :func:`gs_km_f`."""
    return GsKm(lat_rad, alt_m).jacobians(_f64(x), _f64(u))[0]


def _euler_kin_rows(phi: float, th: float) -> list[list[float]]:
    """Body rates -> Euler rates, E(phi, theta) (Lu2016 eq. 18 rows 4-6)."""
    sph, cph = math.sin(phi), math.cos(phi)
    sth, cth = math.sin(th), math.cos(th)
    return [[1.0, sph * sth / cth, cph * sth / cth], [0.0, cph, -sph], [0.0, sph / cth, cph / cth]]


def gs_km_G(x: Vec) -> Mat:
    """Noise/fault distribution ``G(x) = -df/du = df/df^i`` (Lu2016 eq. 13), shape (6, 6)."""
    G = np.empty((N_X, N_U))
    load_kernels("gcs_monitor.models._kinematics_jit").input_matrix(_f64(x), G)
    return G


def gs_km_jac_u(x: Vec) -> Mat:
    """``df/du`` of the GS-KM, shape (6, 6); independent of u and of the earth terms."""
    return -gs_km_G(x)


def gs_km_h(x: Vec) -> Vec:
    """GS-KM output ``h(x) = x`` (Lu2016 eq. 14)."""
    return np.array(x, dtype=np.float64)


def gs_km_jac_h(x: Vec) -> Mat:
    """``dh/dx = I`` for the GS-KM (Lu2016 eq. 14)."""
    return np.eye(N_X)


# ---------------------------------------------------------------------------------------------
# AS-KM
# ---------------------------------------------------------------------------------------------


def _as_km_rates(x: list[float], u: list[float], g: float) -> list[float]:
    ua, va, wa, phi, th, _psi = x
    ax, ay, az, p, q, r = u
    sph, cph = math.sin(phi), math.cos(phi)
    sth, cth = math.sin(th), math.cos(th)
    qsr = q * sph + r * cph
    return [
        ax + va * r - wa * q - g * sth,
        ay - ua * r + wa * p + g * cth * sph,
        az + ua * q - va * p + g * cth * cph,
        p + qsr * sth / cth,
        q * cph - r * sph,
        qsr / cth,
    ]


def as_km_f(x: Vec, u: Vec, lat_rad: float, alt_m: float) -> Vec:
    """AS-KM state derivative (Lu2016 eq. 18 without the noise terms), gravity from eq. 12.

    Parameters
    ----------
    x : (6,) [u_a, v_a, w_a (m/s, body FRD airspeed), phi, theta, psi (rad)]
    u : (6,) IMU input (FRD), fault-corrected ``u_m - f_hat``
    lat_rad, alt_m : used only for the gravity magnitude (Lu2016 eq. 12)
    """
    return np.array(_as_km_rates(list(x), list(u), gravity_mps2(lat_rad, alt_m)))


def _as_km_jac_x_rows(x: list[float], u: list[float], g: float) -> list[list[float]]:
    _ua, _va, _wa, phi, th, _psi = x
    _ax, _ay, _az, p, q, r = u
    sph, cph = math.sin(phi), math.cos(phi)
    sth, cth = math.sin(th), math.cos(th)
    qsr = q * sph + r * cph
    qcr = q * cph - r * sph
    c2 = cth * cth
    return [
        [0.0, r, -q, 0.0, -g * cth, 0.0],
        [-r, 0.0, p, g * cth * cph, -g * sth * sph, 0.0],
        [q, -p, 0.0, -g * cth * sph, -g * sth * cph, 0.0],
        [0.0, 0.0, 0.0, qcr * sth / cth, qsr / c2, 0.0],
        [0.0, 0.0, 0.0, -qsr, 0.0, 0.0],
        [0.0, 0.0, 0.0, qcr / cth, qsr * sth / c2, 0.0],
    ]


def as_km_jac_x(x: Vec, u: Vec, lat_rad: float, alt_m: float) -> Mat:
    """``df/dx`` of the AS-KM, shape (6, 6)."""
    return np.array(_as_km_jac_x_rows(list(x), list(u), gravity_mps2(lat_rad, alt_m)))


def _as_km_jac_u_rows(x: list[float]) -> list[list[float]]:
    ua, va, wa, phi, th, _psi = x
    e = _euler_kin_rows(phi, th)
    return [
        [1.0, 0.0, 0.0, 0.0, -wa, va],
        [0.0, 1.0, 0.0, wa, 0.0, -ua],
        [0.0, 0.0, 1.0, -va, ua, 0.0],
        [0.0, 0.0, 0.0, *e[0]],
        [0.0, 0.0, 0.0, *e[1]],
        [0.0, 0.0, 0.0, *e[2]],
    ]


def as_km_jac_u(x: Vec) -> Mat:
    """``df/du`` of the AS-KM, shape (6, 6)."""
    return np.array(_as_km_jac_u_rows(list(x)))


def as_km_G(x: Vec) -> Mat:
    """AS-KM noise/fault distribution ``G(x') = -df/du`` (Lu2016 eq. 19)."""
    return -as_km_jac_u(x)


def _as_km_h_list(x: list[float]) -> list[float]:
    ua, va, wa, phi, th, psi = x
    v = math.sqrt(ua * ua + va * va + wa * wa)
    return [v, math.atan2(wa, ua), math.asin(va / v), phi, th, psi]


def as_km_h(x: Vec) -> Vec:
    """AS-KM output ``[V, alpha, beta, phi, theta, psi]`` (Lu2016 eqs. 16, 20).

    ``V = |V_a|``, ``alpha = atan2(w_a, u_a)``, ``beta = asin(v_a / V)`` (the standard air-data
    relations; Lu2016 defers ``h`` to its ref. [26]).
    """
    return np.array(_as_km_h_list(list(x)))


def _as_km_jac_h_rows(x: list[float]) -> list[list[float]]:
    ua, va, wa = x[0], x[1], x[2]
    uw2 = ua * ua + wa * wa
    v2 = uw2 + va * va
    v = math.sqrt(v2)
    uw = math.sqrt(uw2)
    rows = [
        [ua / v, va / v, wa / v, 0.0, 0.0, 0.0],
        [-wa / uw2, 0.0, ua / uw2, 0.0, 0.0, 0.0],
        [-ua * va / (v2 * uw), uw / v2, -va * wa / (v2 * uw), 0.0, 0.0, 0.0],
    ]
    rows += [[0.0] * 3 + [1.0 if i == j else 0.0 for j in range(3)] for i in range(3)]
    return rows


def as_km_jac_h(x: Vec) -> Mat:
    """``dh/dx'`` of the AS-KM output, shape (6, 6)."""
    return np.array(_as_km_jac_h_rows(list(x)))


# ---------------------------------------------------------------------------------------------
# Model objects in the form the two-stage filter consumes (filters.two_stage.TwoStageModel);
# the filter discretises F and G itself (Lu2016 eqs. 33-34, filters.two_stage.discretise_series)
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class GsKm:
    """GS-KM at one latitude/altitude, in the form the two-stage filter consumes.

    Attributes
    ----------
    lat_rad : latitude delta (rad), from GPS
    alt_m : altitude h (m), from GPS
    """

    lat_rad: float
    alt_m: float

    def propagate(self, x: Vec, u0: Vec, u1: Vec, dt_s: float) -> Vec:
        """``x + int_{t0}^{t1} f(x, u) dt`` by Heun's method, input linear between samples."""
        out = np.empty(N_X)
        g = gravity_mps2(self.lat_rad, self.alt_m)
        load_kernels("gcs_monitor.models._kinematics_jit").propagate(
            _f64(x), _f64(u0), _f64(u1), self.lat_rad, self.alt_m, g, float(dt_s), out)
        return out

    def jacobians(self, x: Vec, u: Vec) -> tuple[Mat, Mat]:
        """``(F, G) = (df/dx, df/df^i)`` at ``(x, u)`` (Lu2016 eqs. 13, 34)."""
        F, G = np.empty((N_X, N_X)), np.empty((N_X, N_U))
        load_kernels("gcs_monitor.models._kinematics_jit").jacobians(
            _f64(x), _f64(u), self.lat_rad, self.alt_m, F, G)
        return F, G

    def h(self, x: Vec) -> Vec:
        return x.copy()

    def h_jac(self, x: Vec) -> Mat:
        return np.eye(N_X)


@dataclass(frozen=True, slots=True)
class AsKm:
    """AS-KM at one latitude/altitude (gravity only), same interface as :class:`GsKm`."""

    lat_rad: float
    alt_m: float

    def propagate(self, x: Vec, u0: Vec, u1: Vec, dt_s: float) -> Vec:
        g = gravity_mps2(self.lat_rad, self.alt_m)
        xl = x.tolist()
        k1 = _as_km_rates(xl, u0.tolist(), g)
        xe = [xi + dt_s * ki for xi, ki in zip(xl, k1, strict=True)]
        k2 = _as_km_rates(xe, u1.tolist(), g)
        half = dt_s / 2.0
        return np.array([xi + half * (a + b) for xi, a, b in zip(xl, k1, k2, strict=True)])

    def jacobians(self, x: Vec, u: Vec) -> tuple[Mat, Mat]:
        xl = x.tolist()
        F = np.array(_as_km_jac_x_rows(xl, u.tolist(), gravity_mps2(self.lat_rad, self.alt_m)))
        G = np.array(_as_km_jac_u_rows(xl))
        np.negative(G, out=G)
        return F, G

    def h(self, x: Vec) -> Vec:
        return np.array(_as_km_h_list(x.tolist()))

    def h_jac(self, x: Vec) -> Mat:
        return np.array(_as_km_jac_h_rows(x.tolist()))
