"""Chen2020's integral-action LPV sliding-mode controller for roll angle and sideslip (sec. IV).

An alternative to the PID-style lateral loops of :mod:`sim_vehicle.autopilot.loops`, selected
explicitly (:class:`SmcAutopilot`, which a study puts in place of ``Simulation.autopilot``); the
PID autopilot stays the default and is not touched. The longitudinal loops, speed and heading
logic stay the PID autopilot's.

Per step, with the (possibly corrected, Chen2020 eq. 24) measurement ``x^_p = [phi, beta, p,
r]`` and the equivalent airspeed (``rho``, eq. 59):

* command pre-filter ``r' = Gamma (r - R_c)`` (eq. 26, whose left side the paper prints as
  ``F(t)``: read ``r'(t)``), ``R_c`` = ``[bank, sideslip]`` of the manoeuvre's Targets;
* integral states ``x_r' = r - C_c x^_p`` (eq. 25);
* regular form ``x^ = T_c [x_r; x^_p]`` (eqs. 30-31, 34) and switching function
  ``s^ = S x^``, ``S = [N I_l]`` (eq. 39; ``N`` fixed as in Chen2020 sec. V, so ``S' = 0``);
* linear part ``v~_l = -S (A~_c x^ + B~_r r) + Phi s^`` (eq. 42), plus ``-S T_c [0; c(rho)]``
  when the model carries a trim offset ``c`` (an identified model; zero for a linearisation);
* nonlinear part ``v~_n = -K P_2 s^ / (||P_2 s^|| + delta)`` (eq. 44 with the sigmoid smoothing
  of Edwards & Spurgeon [17], the one Chen2020 sec. V uses for its observer's injection:
  ``delta`` bounds the gain of the unit vector near ``s^ = 0`` to ``K / delta``, which an
  explicit-Euler step at 100 Hz and the servos' lag need; a boundary-layer saturation
  ``sat(w / delta)`` would do the same with a corner at ``||w|| = delta``: the sigmoid is
  smooth, as the observer's);
* two additions of ours, not in Chen2020, which an aircraft with little roll authority needs
  (the transport's full aileron holds about 3 deg/s of roll rate against its roll damping at
  250 kt; the S-turn asks for 40 deg in 10 s): the pre-filtered roll command's rate is capped
  at the PID autopilot's roll-rate limit (``ROLL_RATE_MARGIN`` of the full-aileron steady roll
  rate), and the integral states are frozen while a surface is at its limit (conditional
  integration, as the PID's integrators). Without them the surfaces saturate, the integrators
  wind up and sliding is lost (measured: ``||s^||`` up to 8.8 rad/s, roll overshoot 15 deg);
* surfaces from the virtual control ``v~ = B_2(rho) u_p`` (eq. 33): ``u_p = B_2^{-1} v~`` (two
  surfaces for two controlled outputs: ``B_2`` is square; a pseudo-inverse otherwise), clipped
  to the airframe's deflection limits.

The design matrices (``N``, ``Phi``, ``P_2``, ``K``) come in as plain arrays
(:class:`SmcGains`); their LMI design is on the monitor side
(``gcs_monitor/filters/lpv_smc_design.py``). Deviations from the paper's text and why:
docs/papers-notes.md, Chen2020.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from gcs_monitor.core.types import Mat, Vec
from gcs_monitor.models.lateral import RHO0_KGPM3, LateralLpv, rho_of
from gcs_monitor.models.lateral_tracking import B_VP_LATERAL, C_C_LATERAL, tracking_form
from sim_vehicle.autopilot.loops import ROLL_RATE_MARGIN, Autopilot, Feedback, Targets
from sim_vehicle.autopilot.trim import Trim
from sim_vehicle.dynamics.airframe import Airframe


@dataclass(frozen=True, slots=True)
class SmcGains:
    """The controller's design (Chen2020 eqs. 26, 39, 42, 44-46), plain arrays.

    N : (l, n) the switching-function gain, ``S = [N I_l]`` (eq. 39), fixed over Omega
    Phi : (l, l) Hurwitz (eq. 42)
    P2 : (l, l) s.p.d., ``P_2 Phi + Phi^T P_2 = -I`` (eq. 45)
    modulation : ``K`` of eq. 46 (rad/s^2, the virtual control's unit), a constant bound over
        Omega
    delta : sigmoid smoothing of the unit vector (eq. 44), in the unit of ``P_2 s^``
    prefilter_s : time constants of the command pre-filter, ``Gamma = -diag(1 / tau)`` (eq. 26)
    C_c : (l, n_x) controlled outputs (eq. 23)
    B_vp : (n_x, l) the fixed input directions (eq. 29)
    """

    N: Mat
    Phi: Mat
    P2: Mat
    modulation: float
    delta: float
    prefilter_s: tuple[float, ...]
    C_c: Mat = field(default_factory=lambda: C_C_LATERAL.copy())
    B_vp: Mat = field(default_factory=lambda: B_VP_LATERAL.copy())

    def __post_init__(self) -> None:
        l_ = self.C_c.shape[0]
        n = self.C_c.shape[1]
        if self.N.shape != (l_, n) or self.Phi.shape != (l_, l_) or self.P2.shape != (l_, l_):
            raise ValueError(f"SmcGains shapes N {self.N.shape}, Phi {self.Phi.shape}, P2 "
                             f"{self.P2.shape}; expected ({l_}, {n}), ({l_}, {l_}), ({l_}, {l_})")
        if len(self.prefilter_s) != l_ or min(self.prefilter_s) <= 0.0:
            raise ValueError(f"prefilter_s needs {l_} positive time constants")
        if self.delta <= 0.0 or self.modulation < 0.0:
            raise ValueError("delta must be > 0 and modulation >= 0")

    @property
    def S(self) -> Mat:
        """``S = [N I_l]`` (Chen2020 eq. 39)."""
        return np.hstack([self.N, np.eye(self.N.shape[0])])

    def to_dict(self) -> dict[str, Any]:
        return {"N": self.N.tolist(), "Phi": self.Phi.tolist(), "P2": self.P2.tolist(),
                "modulation": self.modulation, "delta": self.delta,
                "prefilter_s": list(self.prefilter_s), "C_c": self.C_c.tolist(),
                "B_vp": self.B_vp.tolist()}

    @staticmethod
    def from_dict(d: dict[str, Any]) -> SmcGains:
        def arr(k: str) -> Mat:
            return np.asarray(d[k], dtype=np.float64)

        return SmcGains(arr("N"), arr("Phi"), arr("P2"), float(d["modulation"]),
                        float(d["delta"]), tuple(float(x) for x in d["prefilter_s"]),
                        arr("C_c"), arr("B_vp"))


def affine_forms(model: LateralLpv, C_c: Mat, B_vp: Mat) -> tuple[list[Mat], list[Mat], Mat]:
    """``A~_c(rho) = sum_k rho_k A~_k`` and ``B_2(rho) = sum_k rho_k B_2k`` (rho_0 = 1) as stacks,
    and the constant ``T_c``: the regular form is linear in ``(A_p, B_p)`` apart from the
    integrators' constant ``-C_c`` block, which belongs to the k = 0 term."""
    zero = tracking_form(np.zeros_like(model.A[0]), np.zeros_like(model.B[0]), C_c, B_vp)
    A_t, B_2 = [], []
    for k in range(3):
        f = tracking_form(model.A[k], model.B[k], C_c, B_vp)
        A_t.append(f.A_t if k == 0 else f.A_t - zero.A_t)
        B_2.append(f.B_2)
    return A_t, B_2, zero.T_c


class LateralSmc:
    """Chen2020's integral-action LPV sliding-mode tracking controller (eqs. 23-46).

    ``update`` takes the measured state ``[phi, beta, p, r]`` (rad, rad/s), the equivalent
    airspeed (m/s, clipped to the model's range Omega) and the command ``R_c`` (rad) and returns
    the surface deflections ``[aileron, rudder]`` (rad). ``s`` holds the last switching
    function ``s^`` (rad/s), ``v`` the last virtual control (rad/s^2).
    """

    def __init__(self, model: LateralLpv, gains: SmcGains,
                 max_deflection_rad: tuple[float, ...]) -> None:
        self.model = model
        self.gains = gains
        self.max_u = np.asarray(max_deflection_rad, dtype=np.float64)
        S = gains.S
        A_t, B_2, T = affine_forms(model, gains.C_c, gains.B_vp)
        self.T = T
        self.SA = [S @ a for a in A_t]  # S A~_k (eq. 42)
        self.B_2 = B_2
        l_ = gains.C_c.shape[0]
        self.l = l_
        self.SB_r = S[:, :l_]  # S B~_r, B~_r = [I_l; 0]
        self.S = S
        # trim offset: S T_c [0; c_k]
        Tn = T[l_:, l_:]
        self.Sc = [S[:, l_:] @ Tn @ model.c[k] for k in range(3)]
        self.gamma = -1.0 / np.asarray(gains.prefilter_s)
        self.x_r = np.zeros(l_)
        self.r: Vec | None = None  # pre-filtered command (eq. 26), set on the first step
        self.s = np.zeros(l_)
        self.v = np.zeros(l_)
        self.saturated = False

    def update(self, x_p: Vec, eas_mps: float, R_c: Vec, dt_s: float,
               rate_max: Vec | None = None) -> Vec:
        """One step (explicit Euler for the pre-filter and the integrators).

        ``rate_max`` (per controlled output, rad/s; None = unlimited) caps the pre-filtered
        command's rate (ours, not in Chen2020: see the module docstring)."""
        g = self.gains
        lo, hi = self.model.eas_range_mps
        r1, r2 = rho_of(min(max(eas_mps, lo), hi))
        y = g.C_c @ x_p
        if self.r is None:
            self.r = y.copy()  # bumpless: the reference starts where the aircraft is
        r = self.r
        xh = self.T @ np.concatenate([self.x_r, x_p])  # eq. 34 (x^_p already corrected)
        s = self.S @ xh  # eq. 39
        SA = self.SA[0] + r1 * self.SA[1] + r2 * self.SA[2]
        Sc = self.Sc[0] + r1 * self.Sc[1] + r2 * self.Sc[2]
        v_l = -(SA @ xh + self.SB_r @ r + Sc) + g.Phi @ s  # eq. 42 (S' = 0: N fixed)
        w = g.P2 @ s
        v_n = -g.modulation * w / (float(np.linalg.norm(w)) + g.delta)  # eq. 44, smoothed
        v = v_l + v_n  # eq. 41
        B2 = self.B_2[0] + r1 * self.B_2[1] + r2 * self.B_2[2]
        if B2.shape[0] == B2.shape[1]:
            u = np.linalg.solve(B2, v)  # eq. 33
        else:
            u = B2.T @ np.linalg.solve(B2 @ B2.T, v)  # minimum-norm u with B_2 u = v
        self.s, self.v = s, v
        saturated = bool(np.any(np.abs(u) > self.max_u))
        self.saturated = saturated
        if not saturated:  # conditional integration (ours): no wind-up while a surface is held
            self.x_r = self.x_r + dt_s * (r - y)  # eq. 25
        rdot = self.gamma * (r - np.asarray(R_c, dtype=np.float64))  # eq. 26
        if rate_max is not None:
            rdot = np.clip(rdot, -rate_max, rate_max)
        self.r = r + dt_s * rdot
        return np.asarray(np.clip(u, -self.max_u, self.max_u), dtype=np.float64)


class SmcAutopilot(Autopilot):
    """The PID autopilot with its lateral loops replaced by :class:`LateralSmc` (aileron and
    rudder); elevator, throttle and the heading-to-bank law stay the PID's. Put it in place of
    ``Simulation.autopilot`` to fly the SMC; nothing selects it by default."""

    def __init__(self, af: Airframe, trim: Trim, g_mps2: float, model: LateralLpv,
                 gains: SmcGains) -> None:
        super().__init__(af, trim, g_mps2)
        lim = af.actuators.max_deflection_rad
        self.smc = LateralSmc(model, gains, (lim[0], lim[2]))

    def update(self, fb: Feedback, tg: Targets, dt_s: float) -> tuple[float, float, float, float]:
        _, de, _, thr = super().update(fb, tg, dt_s)
        # the PID's bank command (heading hold when the manoeuvre gives no bank)
        phi_c = tg.bank_rad if tg.bank_rad is not None else self.setpoints.phi_rad
        eas = fb.tas_mps * math.sqrt(fb.rho_kgpm3 / RHO0_KGPM3)
        # the PID's roll-rate limit (loops.py): the roll command's rate stays within what the
        # aileron can hold against the roll damping
        a, geo = self.af.aero, self.af.geometry
        v = max(fb.tas_mps, 1.0)
        p_max = ROLL_RATE_MARGIN * abs(a.croll_da * self.af.actuators.max_deflection_rad[0]
                                       / a.croll_p) * 2.0 * v / geo.span_m
        u = self.smc.update(np.array([fb.phi, fb.beta, fb.p, fb.r]), eas,
                            np.array([phi_c, tg.beta_rad]), dt_s, np.array([p_max, math.inf]))
        lim = self.af.actuators.max_deflection_rad
        da = float(np.clip(u[0] + tg.surface_offset_rad[0], -lim[0], lim[0]))
        dr = float(np.clip(u[1] + tg.surface_offset_rad[2], -lim[2], lim[2]))
        return da, de, dr, thr
