"""Manoeuvre scripts: turn (time, state) into autopilot :class:`Targets`.

Kinds (``ManoeuvreConfig.kind``), with ``tau = t - start_s`` and defaults from the airframe
file's ``[autopilot]`` table when ``amplitude``/``period_s`` are 0:

``level``            hold the initial altitude, airspeed and heading.
``doublet_3211``     3-2-1-1 on ``surface`` added to the loop output: +A for 3T, -A for 2T,
                     +A for T, -A for T (A = doublet_amplitude_rad, T = doublet_period_s).
``s_turn``           Chen2020: bank +20 deg for P, -20 deg for P, wings level for P, then sideslip
                     -2 deg for P and +3 deg for P (P = period_s, default 10 s); amplitude
                     overrides the bank (rad).
``parabolic``        Lu2016 scenario 2 (zero-g): pull at 1 + pull_g until gamma >= gamma_e, track
                     n_z = 0 until gamma <= -gamma_e, pull out at 1 + pull_g until gamma >= 0,
                     then altitude hold (climb back). amplitude overrides gamma_e (rad).
``coordinated_turn`` constant bank (amplitude, default 30 deg), beta = 0; period_s = turn
                     duration (0 = for ever, or 30 s when repeating) then wings level.
``decel``            airspeed target ramps down by amplitude (m/s, default decel_amplitude_mps)
                     at decel_rate_mps2, altitude held; period_s (default 30 s) before the
                     return ramp when repeating.
``climb``            altitude target steps by amplitude (m, negative = descent; default
                     climb_amplitude_m); climb rate limited by the loop; when repeating,
                     alternates up/down every period_s (default 60 s).

``repeat`` restarts the manoeuvre every cycle (its length plus a settling time).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from gcs_monitor.core.units import DEG2RAD
from sim_vehicle.autopilot.loops import Feedback, Targets
from sim_vehicle.dynamics.airframe import AutopilotGains

MANOEUVRE_KINDS = (
    "level",
    "doublet_3211",
    "s_turn",
    "parabolic",
    "coordinated_turn",
    "decel",
    "climb",
)
SURFACE_INDEX = {"aileron": 0, "elevator": 1, "rudder": 2}
S_TURN_BANK_RAD = 20.0 * DEG2RAD  # Chen2020 S-turn
S_TURN_BETA_RAD = (-2.0 * DEG2RAD, 3.0 * DEG2RAD)  # Chen2020 sideslip phase
S_TURN_PERIOD_S = 10.0
TURN_BANK_RAD = 30.0 * DEG2RAD
TURN_PERIOD_REPEAT_S = 30.0
DECEL_HOLD_S = 30.0
CLIMB_PERIOD_S = 60.0
SETTLE_S = 15.0
PARABOLA_PHASE_TIMEOUT_S = 20.0


@dataclass(frozen=True, slots=True)
class ManoeuvreSpec:
    kind: str = "level"
    start_s: float = 10.0
    amplitude: float = 0.0
    surface: str = "elevator"
    period_s: float = 0.0
    repeat: bool = False


class ManoeuvreScript:
    def __init__(
        self,
        spec: ManoeuvreSpec,
        gains: AutopilotGains,
        alt_m: float,
        tas_mps: float,
        heading_rad: float,
    ) -> None:
        if spec.kind not in MANOEUVRE_KINDS:
            raise ValueError(f"unknown manoeuvre {spec.kind!r}; expected one of {MANOEUVRE_KINDS}")
        if spec.surface not in SURFACE_INDEX:
            raise ValueError(
                f"unknown surface {spec.surface!r}; expected one of {tuple(SURFACE_INDEX)}"
            )
        self.spec = spec
        self.gn = gains
        self.alt0 = alt_m
        self.tas0 = tas_mps
        self.base = Targets(alt_m, tas_mps, heading_rad)
        k = spec.kind
        a, p = spec.amplitude, spec.period_s
        if k == "doublet_3211":
            self.amp = a or gains.doublet_amplitude_rad
            self.per = p or gains.doublet_period_s
            self.cycle = 7.0 * self.per + SETTLE_S
        elif k == "s_turn":
            self.amp = a or S_TURN_BANK_RAD
            self.per = p or S_TURN_PERIOD_S
            self.cycle = 5.0 * self.per + SETTLE_S
        elif k == "parabolic":
            self.amp = a or gains.parabola_gamma_rad
            self.per = p
            self.cycle = 4.0 * PARABOLA_PHASE_TIMEOUT_S + SETTLE_S
        elif k == "coordinated_turn":
            self.amp = a or TURN_BANK_RAD
            self.per = p or (TURN_PERIOD_REPEAT_S if spec.repeat else math.inf)
            self.cycle = self.per + SETTLE_S
        elif k == "decel":
            self.amp = a or gains.decel_amplitude_mps
            self.per = p or DECEL_HOLD_S
            self.cycle = 2.0 * (self.per + self.amp / gains.decel_rate_mps2)
        elif k == "climb":
            self.amp = a or gains.climb_amplitude_m
            self.per = p or CLIMB_PERIOD_S
            self.cycle = 2.0 * self.per
        else:
            self.amp, self.per, self.cycle = 0.0, 0.0, math.inf
        self._phase = 0
        self._phase_t0 = 0.0
        self._cycle_idx = -1
        self._hdg_hold = heading_rad

    def targets(self, t_s: float, fb: Feedback) -> Targets:
        sp = self.spec
        tau = t_s - sp.start_s
        if sp.kind == "level" or tau < 0.0:
            return self.base
        if sp.repeat and math.isfinite(self.cycle):
            n = int(tau // self.cycle)
            tau -= n * self.cycle
        else:
            n = 0
        if n != self._cycle_idx:
            self._cycle_idx = n
            self._phase = 0
            self._phase_t0 = t_s
            self._hdg_hold = fb.psi
        k = sp.kind
        b = self.base
        if k == "doublet_3211":
            T = self.per
            seq = ((3.0, 1.0), (2.0, -1.0), (1.0, 1.0), (1.0, -1.0))
            t_acc = 0.0
            off = 0.0
            for dur, sgn in seq:
                if t_acc <= tau < t_acc + dur * T:
                    off = sgn * self.amp
                    break
                t_acc += dur * T
            offs = [0.0, 0.0, 0.0]
            offs[SURFACE_INDEX[sp.surface]] = off
            return Targets(b.alt_m, b.tas_mps, b.heading_rad, surface_offset_rad=tuple(offs))  # type: ignore[arg-type]
        if k == "s_turn":
            P = self.per
            if tau < P:
                return Targets(b.alt_m, b.tas_mps, b.heading_rad, bank_rad=self.amp)
            if tau < 2.0 * P:
                return Targets(b.alt_m, b.tas_mps, b.heading_rad, bank_rad=-self.amp)
            if tau < 3.0 * P:
                return Targets(b.alt_m, b.tas_mps, b.heading_rad, bank_rad=0.0)
            if tau < 4.0 * P:
                return Targets(
                    b.alt_m, b.tas_mps, b.heading_rad, bank_rad=0.0, beta_rad=S_TURN_BETA_RAD[0]
                )
            if tau < 5.0 * P:
                return Targets(
                    b.alt_m, b.tas_mps, b.heading_rad, bank_rad=0.0, beta_rad=S_TURN_BETA_RAD[1]
                )
            return Targets(
                b.alt_m, b.tas_mps, fb.psi if self._phase == 0 else self._hdg_hold, bank_rad=0.0
            )
        if k == "parabolic":
            ge = self.amp
            pull = 1.0 + self.gn.parabola_pull_g
            dt_phase = t_s - self._phase_t0
            ph = self._phase
            if ph == 0 and (fb.gamma_rad >= ge or dt_phase > PARABOLA_PHASE_TIMEOUT_S):
                ph = 1
            elif ph == 1 and (fb.gamma_rad <= -ge or dt_phase > PARABOLA_PHASE_TIMEOUT_S):
                ph = 2
            elif ph == 2 and (fb.gamma_rad >= 0.0 or dt_phase > PARABOLA_PHASE_TIMEOUT_S):
                ph = 3
            if ph != self._phase:
                self._phase = ph
                self._phase_t0 = t_s
            if ph == 0:
                return Targets(b.alt_m, b.tas_mps, b.heading_rad, load_factor=pull)
            if ph == 1:
                return Targets(b.alt_m, b.tas_mps, b.heading_rad, load_factor=0.0)
            if ph == 2:
                return Targets(b.alt_m, b.tas_mps, b.heading_rad, load_factor=pull)
            return b
        if k == "coordinated_turn":
            if tau < self.per:
                return Targets(b.alt_m, b.tas_mps, b.heading_rad, bank_rad=self.amp)
            return Targets(b.alt_m, b.tas_mps, b.heading_rad, bank_rad=0.0)
        if k == "decel":
            ramp = self.amp / self.gn.decel_rate_mps2
            if tau < ramp + self.per or not sp.repeat:
                dv = min(tau * self.gn.decel_rate_mps2, self.amp)
            else:
                dv = max(self.amp - (tau - ramp - self.per) * self.gn.decel_rate_mps2, 0.0)
            return Targets(b.alt_m, b.tas_mps - dv, b.heading_rad)
        # climb
        up = tau < self.per or not sp.repeat
        return Targets(b.alt_m + (self.amp if up else 0.0), b.tas_mps, b.heading_rad)
