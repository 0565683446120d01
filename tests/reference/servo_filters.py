"""Numpy reference of one surface's filter step (``families/actuators/_servo_filters_jit.py``).

The same sequence as the kernel, from Python: the command-sampling covariance at the IOTSEKF's
estimate (``models._servo_jit.command_timing_noise``, twice), the closed-loop propagation with
its discretisation (``models.servo.propagate``), the IOTSEKF step (``filters.iotsekf``) and the
RTS-EKF time and measurement updates (``filters.three_step``). The equivalence test compares
the two on recorded SURF samples.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from gcs_monitor.families.actuators._servo_filters_jit import (
    LEAD_CLIP_SIGMAS,
    LEAD_FRACTIONS,
    LEAD_SMOOTH,
)
from gcs_monitor.families.actuators.servo_filters import ServoFilterConfig, ServoSensors
from gcs_monitor.filters.iotsekf import iotsekf_init, iotsekf_step
from gcs_monitor.filters.three_step import three_step_predict, three_step_update
from gcs_monitor.models.servo import (
    ServoLoopParams,
    ServoParams,
    command_timing_noise,
    ndi_control,
    pack_params,
    propagate,
    reference_model_derivative,
)


class ReferenceServoFilters:
    """``ServoFilters`` from its parts (``start`` / ``step`` with the same arguments; ``out``
    as a dict)."""

    def __init__(self, servo: ServoParams, loop: ServoLoopParams, sensors: ServoSensors,
                 cfg: ServoFilterConfig) -> None:
        self.servo, self.loop, self.sensors, self.cfg = servo, loop, sensors, cfg
        self.prm = pack_params(servo, loop, sensors.rod_stroke_m)

    def rod_command(self, cmd_rad: float) -> float:
        st = self.sensors.rod_stroke_m
        return min(st, max(-st, cmd_rad / self.sensors.rod_gain_radpm))

    def start(self, cmd_rad: float, y_rod_m: float) -> None:
        c = self.cfg
        sig = [self.sensors.rod_sigma_m, c.velocity_init_sigma_mps, c.pressure_init_sigma,
               *c.reference_init_sigma]
        P0 = np.diag(np.square(sig))
        x0 = np.array([y_rod_m, 0.0, 0.0, y_rod_m, 0.0, 0.0])
        self.iots = iotsekf_init(x0, P0, np.zeros(1), np.array([[c.fault_init_sigma ** 2]]),
                                 np.zeros((1, 1)), m=1)
        self.x_nom, self.P_nom = x0.copy(), P0.copy()
        self.q_com = self.rod_command(cmd_rad)
        self.q_prev = math.nan
        self.d2: list[float] = []  # |second differences| of the command seen
        self.q_max = 0.0  # the largest |rod command| seen since the start
        self.q_lim = 0.0  # |rod command| the command was seen held at (its limit)
        self.lim_since = 0  # samples since the last interval with a sample at the limit
        self.j_hold = 0.0  # the spread of the last sample not held at the limit
        self.x_early, self.x_late = x0.copy(), x0.copy()
        if not hasattr(self, "lead_j"):  # the identified command timing survives a restart
            self.lead_j = [0.0] * len(LEAD_FRACTIONS)
            self.lead_i = -1
            self.dt_ref = 0.0
            self.lead_x = [x0.copy() for _ in LEAD_FRACTIONS]
            self.lead_k = 0

    def _lead(self, dt: float) -> float:
        """The command lead of this interval (``_servo_filters_jit.command_lead``)."""
        c = self.cfg
        self.dt_ref = dt if self.dt_ref <= 0.0 or dt < self.dt_ref else self.dt_ref
        if c.command_lead_window_s <= 0.0:
            return c.command_lead_s
        if self.lead_i < 0:
            errs = [abs(fr * self.dt_ref - c.command_lead_s) for fr in LEAD_FRACTIONS]
            self.lead_i = errs.index(min(errs))
        return LEAD_FRACTIONS[self.lead_i] * self.dt_ref

    def _identify(self, anchor: np.ndarray, qc0: float, qc1: float, y_rod: float, dt: float,
                  n_sub: int) -> tuple[list[float], list[np.ndarray], int, int]:
        """The discounted rod errors of each candidate lead's nominal servo, those servos, the
        lead of the next interval and the samples since the anchor
        (``_servo_filters_jit.identify_lead``)."""
        c = self.cfg
        d1, d2 = qc1 - qc0, qc1 - 2.0 * qc0 + self.q_prev
        if not abs(d2) <= LEAD_SMOOTH * abs(d1):
            return self.lead_j, self.lead_x, self.lead_i, 0
        lam = math.exp(-dt / c.command_lead_window_s)
        clip = LEAD_CLIP_SIGMAS * self.sensors.rod_sigma_m
        lj, lx = [], []
        for j, fr in enumerate(LEAD_FRACTIONS):
            x0 = anchor if self.lead_k == 0 else self.lead_x[j]
            knee = max(dt - fr * self.dt_ref, 0.0)
            x1 = propagate(x0, qc0, qc1, 0.0, dt, n_sub, self.prm, knee_s=knee).s
            lj.append(lam * self.lead_j[j] + min(abs(x1[0] - y_rod), clip) ** 2)
            lx.append(x1)
        best = int(np.argmin(lj))
        li = self.lead_i
        margin = c.command_lead_switch * self.sensors.rod_sigma_m ** 2
        k = (self.lead_k + 1) % c.command_lead_segment
        return lj, lx, best if lj[li] - lj[best] > margin else li, k

    def step(self, dt: float, cmd_rad: float, y_rod: float, y_surf_rad: float
             ) -> dict[str, float] | None:
        c, prm = self.cfg, self.prm
        qc0, qc1 = self.q_com, self.rod_command(cmd_rad)
        n_sub = max(1, math.ceil(dt / c.substep_s - 1e-9))
        lead = self._lead(dt)
        knee = max(dt - lead, 0.0)
        qs = (*c.state_noise_psd, 0.0, 0.0, 0.0)
        jit = 0.0
        if c.command_jitter_noise and self.q_prev == self.q_prev:
            d2 = abs(qc1 - 2.0 * qc0 + self.q_prev)
            n = max(3, min(64, round(c.command_jitter_window_s / dt)))
            seen = sorted([d2] + self.d2[::-1][:n - 1])
            kept = seen[:-2] if len(seen) > 4 else seen
            jit = 0.5 * math.sqrt(sum(x * x for x in kept) / len(seen))
            self.d2.append(d2)
            # a command held at its largest deflection so far (clipped) is at its limit; over
            # an interval with a sample at the limit, and while the window holds one, the
            # spread is not below the one it had when it got there
            if qc1 == qc0 == self.q_prev and abs(qc1) >= self.q_max > 0.0:
                self.q_lim = abs(qc1)
            self.lim_since += 1
            if self.q_lim > 0.0 and max(abs(qc0), abs(qc1)) >= self.q_lim:
                self.lim_since = 0
            if self.q_lim > 0.0 and self.lim_since < n:
                jit = max(jit, self.j_hold)
            else:
                self.j_hold = jit
        s = self.iots
        f0 = float(s.f[0])
        ident = (self._identify(s.x, qc0, qc1, y_rod, dt, n_sub)
                 if c.command_lead_window_s > 0.0 else None)
        Qt = np.zeros((6, 6))
        if c.command_step_noise:
            Qt += command_timing_noise(s.x, qc0, qc1, f0, dt, n_sub, prm)
        if c.command_jitter_noise and jit > 0.0:
            Qt += 3.0 * command_timing_noise(s.x, qc0, qc0 + jit, f0, dt, n_sub, prm)
        pr = propagate(s.x, qc0, qc1, f0, dt, n_sub, prm, q_valve=c.valve_noise_psd,
                       q_state=qs, knee_s=knee)
        Qd = pr.Qd + Qt
        if c.bias_free_from_blend:
            xbp = pr.s - (pr.Phi @ s.V[:, 0] + pr.Gamma) * f0
        else:
            xbp = propagate(s.x_bar, qc0, qc1, 0.0, dt, n_sub, prm, knee_s=knee).s
        H1 = np.array([[1.0, 0.0, 0.0, 0.0, 0.0, 0.0]])
        s = dataclasses.replace(s, Qf=np.array([[(c.fault_rate_sigma * dt) ** 2]]))
        new, innov = iotsekf_step(s, xbp, pr.Phi, pr.Gamma.reshape(6, 1), Qd, H1,
                                  np.array([y_rod]), np.array([[self.sensors.rod_sigma_m ** 2]]),
                                  gate_sigma=c.gate_sigma)
        if not innov.numerics_ok:
            return None
        prn = propagate(self.x_nom, qc0, qc1, 0.0, dt, n_sub, prm, q_valve=c.valve_noise_psd,
                        q_state=qs, knee_s=knee)
        P_pred = three_step_predict(self.P_nom, prn.Phi, prn.Qd + Qt)
        g = self.sensors.rod_gain_radpm
        H2 = np.zeros((2, 6))
        H2[:, 0] = 1.0
        R2 = np.diag([self.sensors.rod_sigma_m ** 2, (self.sensors.surf_sigma_rad / g) ** 2])
        y2 = np.array([y_rod, y_surf_rad / g])
        rts, _ = three_step_update(prn.s, P_pred, y2, H2 @ prn.s, H2, np.eye(2), R2,
                                   gate_sigma=c.gate_sigma)
        if rts is None:
            return None
        self.x_early = propagate(self.x_early, qc1, qc1, 0.0, dt, n_sub, prm).s
        self.x_late = propagate(self.x_late, qc0, qc0, 0.0, dt, n_sub, prm).s
        env = self.x_early[0] - self.x_late[0]
        self.iots, self.x_nom, self.P_nom = new, rts.x, rts.P
        self.q_prev, self.q_com = qc0, qc1
        self.q_max = max(self.q_max, abs(qc1))
        if ident is not None:
            self.lead_j, self.lead_x, self.lead_i, self.lead_k = ident
        x = new.x
        _, _, rddd = reference_model_derivative(x[3], x[4], x[5], qc1, self.loop)
        u = ndi_control(x[0], x[1], x[2], (x[3], x[4], x[5], rddd), self.servo, self.loop)
        Pf = rts.Pf
        return {"f_in": float(new.f[0]), "u": u + float(new.f[0]), "x": x[:3].copy(),
                "x_nom": rts.x[:3].copy(), "f_rod": float(rts.f[0]), "f_surf": float(rts.f[1]),
                "sf_rod": math.sqrt(Pf[0, 0] + env * env / 12.0), "env": env,
                "sf_d": math.sqrt(Pf[0, 0] + Pf[1, 1] - 2.0 * Pf[0, 1]), "jit": jit,
                "nu": float(innov.nu[0]), "lead": lead}
