"""Wind: constant mean, microburst-like shear and Dryden turbulence (Lu2016 sec. 2.2.1).

Shear (our choice, in the style of Lu2016 Fig. 1a, which is adapted from its ref. [28])
---------------------------------------------------------------------------------------
Earth-axis components, ``v_w = 0``, starting at ``t0`` with amplitude ``A`` and duration ``T``:

* horizontal ``u_w(t) = -A/2 (1 - cos(2 pi tau / T))`` along the aircraft's initial heading
  (a head-wind that rises and decays, i.e. the outflow of a microburst), and
* vertical ``w_w(t) = +(A/2) sin(pi tau / T)^2 * (vertical_ratio)`` down-draft (NED +down),

for ``0 <= tau = t - t0 <= T``, zero outside. ``T`` = 20 s, vertical ratio 0.5 by default;
both vary smoothly over several seconds.

Dryden turbulence (Lu2016 eqs. 21-23)
-------------------------------------
Generated in body axes (u along the body x axis, v lateral, w vertical, as in MIL-F-8785C
and the MATLAB Dryden block), then rotated into NED with the aircraft attitude. Forming
filters driven by unit white noise, with ``tau = L/V``:

* ``H_u(s) = sigma sqrt(2 tau) / (1 + tau s)``
* ``H_v(s) = H_w(s) = sigma sqrt(tau) (1 + sqrt(3) tau s) / (1 + tau s)^2``

whose one-sided spectra ``Phi(omega) = |H(j omega)|^2 / pi`` (so that the integral over
``omega in [0, inf)`` is sigma^2) are exactly eqs. 21-23. Note: Lu2016 prints eqs. 22-23
with ``1 + (L omega / V)^2`` in the denominator; the Dryden lateral/vertical spectrum has it
*squared* (otherwise the variance is infinite). We implement the squared (physical) form.

The filters are discretised exactly (zero-order-hold-free: state transition ``e^{A dt}`` and
the exact sampled process-noise covariance by Van Loan's method), re-discretised when the
airspeed changes by more than ``REDISCRETISE_REL`` (2 %).
"""

from __future__ import annotations

import math
from typing import cast

import numpy as np
from scipy.linalg import expm

from gcs_monitor.core.types import Vec

REDISCRETISE_REL = 0.02  # relative airspeed change that triggers a new exact discretisation
MIN_AIRSPEED_MPS = 1.0  # the forming filters need V > 0
SHEAR_DURATION_S = 20.0
SHEAR_VERTICAL_RATIO = 0.5
NOISE_BLOCK = 1024  # turbulence steps of white noise drawn at once


def dryden_psd(
    omega_radps: Vec, sigma_mps: float, scale_m: float, tas_mps: float
) -> tuple[Vec, Vec, Vec]:
    """One-sided Dryden spectra Phi_u, Phi_v, Phi_w in (m/s)^2/(rad/s) (Lu2016 eqs. 21-23).

    Eqs. 22-23 with the squared denominator (see module note).
    """
    x2 = (scale_m * omega_radps / tas_mps) ** 2
    k = sigma_mps**2 * scale_m / (math.pi * tas_mps)
    phi_u = 2.0 * k / (1.0 + x2)
    phi_vw = k * (1.0 + 3.0 * x2) / (1.0 + x2) ** 2
    return phi_u, phi_vw, phi_vw.copy()


def _discretise(a: np.ndarray, b: np.ndarray, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact discretisation of ``x' = A x + B w`` (unit white w): Phi and chol(Qd) (Van Loan)."""
    n = a.shape[0]
    m = np.zeros((2 * n, 2 * n))
    m[:n, :n] = -a
    m[:n, n:] = b @ b.T
    m[n:, n:] = a.T
    e = expm(m * dt_s)
    phi = e[n:, n:].T
    qd = phi @ e[:n, n:]
    qd = 0.5 * (qd + qd.T)
    # Cholesky with a tiny jitter: Qd of the 2-state filter is near-singular for dt << tau.
    lq = np.linalg.cholesky(qd + np.eye(n) * 1e-18 * max(1.0, float(np.trace(qd))))
    return phi, lq


class DrydenTurbulence:
    """Body-axis Dryden turbulence (Lu2016 eqs. 21-23), exact discrete forming filters.

    Parameters
    ----------
    sigma_mps : intensity sigma_u = sigma_v = sigma_w (Lu2016: 3.54 m/s)
    scale_m : scale length L_u = L_v = L_w (Lu2016: 530 m)
    dt_s : sample interval
    rng : seeded generator
    """

    def __init__(
        self, sigma_mps: float, scale_m: float, dt_s: float, rng: np.random.Generator
    ) -> None:
        self.sigma_mps = sigma_mps
        self.scale_m = scale_m
        self.dt_s = dt_s
        self.rng = rng
        self._v_disc = -1.0
        self.xu = 0.0
        self.xv = [0.0, 0.0]
        self.xw = [0.0, 0.0]
        self._started = False
        self._noise: list[list[float]] = []  # pre-drawn unit normals, 5 per step
        self._row = 0

    def _update_discretisation(self, tas_mps: float) -> None:
        v = max(tas_mps, MIN_AIRSPEED_MPS)
        tau = self.scale_m / v
        s = self.sigma_mps
        # u: x' = -x/tau + sigma sqrt(2/tau) w  (H_u above, output y = x)
        self.phi_u = math.exp(-self.dt_s / tau)
        self.q_u = s * math.sqrt(1.0 - self.phi_u**2)
        # v, w: controllable canonical form of sigma sqrt(tau) (1 + sqrt3 tau s)/(tau s + 1)^2
        a = np.array([[0.0, 1.0], [-1.0 / tau**2, -2.0 / tau]])
        b = np.array([[0.0], [1.0]])
        g = s * math.sqrt(tau) / tau**2
        self.c_vw = (g, g * math.sqrt(3.0) * tau)
        phi, lq = _discretise(a, b, self.dt_s)
        self.phi_vw = [[float(phi[0, 0]), float(phi[0, 1])], [float(phi[1, 0]), float(phi[1, 1])]]
        self.l_vw = [[float(lq[0, 0]), 0.0], [float(lq[1, 0]), float(lq[1, 1])]]
        self._v_disc = v
        if not self._started:
            # Start from the stationary distribution so there is no spin-up transient.
            self.xu = s * float(self.rng.standard_normal())
            pinf = _stationary_cov(a, b)
            lp = np.linalg.cholesky(pinf)
            for x in (self.xv, self.xw):
                z = self.rng.standard_normal(2)
                x[0], x[1] = (float(v_) for v_ in lp @ z)
            self._started = True

    def output(self) -> tuple[float, float, float]:
        c0, c1 = self.c_vw
        return self.xu, c0 * self.xv[0] + c1 * self.xv[1], c0 * self.xw[0] + c1 * self.xw[1]

    def step(self, tas_mps: float) -> tuple[float, float, float]:
        """Advance one ``dt_s`` at airspeed ``tas_mps``; return body-axis (u, v, w) gust, m/s."""
        if abs(tas_mps - self._v_disc) > REDISCRETISE_REL * self._v_disc:
            self._update_discretisation(tas_mps)
        if self._row >= len(self._noise):
            # Drawn in blocks: the same numbers, in the same order, as one draw of 5 per step.
            self._noise = self.rng.standard_normal((NOISE_BLOCK, 5)).tolist()
            self._row = 0
        n = self._noise[self._row]
        self._row += 1
        self.xu = self.phi_u * self.xu + self.q_u * n[0]
        p = self.phi_vw
        lq = self.l_vw
        for x, n0, n1 in ((self.xv, n[1], n[2]), (self.xw, n[3], n[4])):
            a0 = p[0][0] * x[0] + p[0][1] * x[1] + lq[0][0] * n0
            a1 = p[1][0] * x[0] + p[1][1] * x[1] + lq[1][0] * n0 + lq[1][1] * n1
            x[0], x[1] = a0, a1
        return self.output()


def _stationary_cov(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    from scipy.linalg import solve_continuous_lyapunov

    return cast(np.ndarray, solve_continuous_lyapunov(a, -b @ b.T))


def shear_ned_mps(
    t_s: float, start_s: float, amplitude_mps: float, heading_rad: float
) -> tuple[float, float, float]:
    """Microburst-like shear in NED (see module docstring), m/s."""
    tau = t_s - start_s
    if tau < 0.0 or tau > SHEAR_DURATION_S or amplitude_mps == 0.0:
        return 0.0, 0.0, 0.0
    u_w = -0.5 * amplitude_mps * (1.0 - math.cos(2.0 * math.pi * tau / SHEAR_DURATION_S))
    w_w = SHEAR_VERTICAL_RATIO * amplitude_mps * math.sin(math.pi * tau / SHEAR_DURATION_S) ** 2
    return u_w * math.cos(heading_rad), u_w * math.sin(heading_rad), w_w


class WindField:
    """Total wind at the aircraft = mean + shear + turbulence (kinds of ``WindConfig``)."""

    def __init__(
        self,
        kind: str,
        mean_ned_mps: tuple[float, float, float],
        *,
        sigma_mps: float,
        scale_m: float,
        shear_start_s: float,
        shear_amplitude_mps: float,
        shear_heading_rad: float,
        dt_s: float,
        rng: np.random.Generator,
    ) -> None:
        kinds = ("calm", "constant", "shear", "turbulence", "shear+turbulence")
        if kind not in kinds:
            raise ValueError(f"unknown wind kind {kind!r}; expected one of {kinds}")
        self.kind = kind
        self.mean = cast(  # mean_ned_mps is a 3-tuple
            tuple[float, float, float],
            tuple(float(v) for v in mean_ned_mps) if kind != "calm" else (0.0, 0.0, 0.0),
        )
        self.shear = "shear" in kind
        self.turb = (
            DrydenTurbulence(sigma_mps, scale_m, dt_s, rng) if "turbulence" in kind else None
        )
        self.shear_start_s = shear_start_s
        self.shear_amplitude_mps = shear_amplitude_mps
        self.shear_heading_rad = shear_heading_rad
        self.gust_frd = (0.0, 0.0, 0.0)

    def advance_turbulence(self, tas_mps: float) -> None:
        if self.turb is not None:
            self.gust_frd = self.turb.step(tas_mps)

    def wind_ned(self, t_s: float, c_ned_frd: tuple[float, ...]) -> tuple[float, float, float]:
        """Total wind (m/s NED); ``c_ned_frd`` is the row-major body-to-NED DCM (9 floats)."""
        wn, we, wd = self.mean
        if self.shear:
            sn, se, sd = shear_ned_mps(
                t_s, self.shear_start_s, self.shear_amplitude_mps, self.shear_heading_rad
            )
            wn += sn
            we += se
            wd += sd
        if self.turb is not None:
            gu, gv, gw = self.gust_frd
            c = c_ned_frd
            wn += c[0] * gu + c[1] * gv + c[2] * gw
            we += c[3] * gu + c[4] * gv + c[5] * gw
            wd += c[6] * gu + c[7] * gv + c[8] * gw
        return wn, we, wd
