"""Actuator fault definitions (Lu2017 sec. IV.A and V.A) and their pure effect function.

Kinds
-----
``liquid_ofc``  sinusoid *added* to the servo control signal u (input fault f^i, Lu2017 eq. 4);
                ``amplitude`` in valve-command units (-), the loop still acts.
``solid_ofc``   sinusoid *replacing* the control signal (the loop no longer acts).
``liquid_jam``  additive bias on the rod position sensor (output fault f^o, Lu2017 eq. 5) while
                the surface is still under control; ``amplitude`` in m of rod. The servo loop
                closes on the biased sensor, so the real rod settles ``-amplitude`` off.
``solid_jam``   the rod is stuck at its position at ``t_start_s`` (surface jammed).
``runaway``     the valve is driven fully open (u = sign(amplitude) * 1, default +1) until the
                rod reaches its mechanical stop, where it stays.

Aircraft-level faults (ALFA's real failures and their simulated counterparts; Keipour 2019):

``stuck_at_zero``          the servo is driven to the neutral position and held there whatever
                           the autopilot commands (ALFA: "surface stuck at zero"); a stuck
                           surface at its current position is ``solid_jam``.
``loss_of_effectiveness``  the surface moves as commanded but produces only ``1 - amplitude``
                           of its aerodynamic effect (part of it missing); ``amplitude`` in
                           0..1. On the engine: thrust scaled by ``1 - amplitude``.
``engine_out``             the engine delivers no thrust whatever the throttle (the propeller
                           windmills); only on the ``engine`` (index 3).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

SERVO_FAULT_KINDS = ("liquid_ofc", "solid_ofc", "liquid_jam", "solid_jam", "runaway")
SURFACE_FAULT_KINDS = (*SERVO_FAULT_KINDS, "stuck_at_zero", "loss_of_effectiveness")
ENGINE_FAULT_KINDS = ("engine_out", "loss_of_effectiveness")
FAULT_KINDS = (*SURFACE_FAULT_KINDS, "engine_out")
SURFACES = ("aileron", "elevator", "rudder")
ACTUATORS = (*SURFACES, "engine")  # fault targets: the three surfaces and the engine
ENGINE = 3


@dataclass(frozen=True, slots=True)
class ActuatorFault:
    """One actuator fault on one surface (0 aileron, 1 elevator, 2 rudder) or the engine (3)."""

    surface: int
    kind: str
    t_start_s: float = 12.0  # Lu2017 Table 1: all scenarios start at t = 12 s
    t_end_s: float | None = None
    # OFC: valve units (-); liquid_jam: m of rod; runaway: sign; loss_of_effectiveness: share
    # of the effect lost (0..1)
    amplitude: float = 0.0
    frequency_hz: float = 0.0  # OFC only
    phase_rad: float = 0.0  # OFC only

    def __post_init__(self) -> None:
        if self.kind not in FAULT_KINDS:
            raise ValueError(f"unknown actuator fault kind {self.kind!r}; expected {FAULT_KINDS}")
        if not 0 <= self.surface < len(ACTUATORS):
            raise ValueError(f"actuator index {self.surface} out of range 0..{len(ACTUATORS) - 1}")
        kinds = ENGINE_FAULT_KINDS if self.surface == ENGINE else SURFACE_FAULT_KINDS
        if self.kind not in kinds:
            raise ValueError(f"{self.kind!r} is not a fault of the {ACTUATORS[self.surface]}; "
                             f"expected one of {kinds}")
        if self.kind == "loss_of_effectiveness" and not 0.0 < self.amplitude <= 1.0:
            raise ValueError(f"loss_of_effectiveness needs 0 < amplitude <= 1 (the share lost), "
                             f"got {self.amplitude}")

    def active(self, t_s: float) -> bool:
        return t_s >= self.t_start_s and (self.t_end_s is None or t_s < self.t_end_s)


@dataclass(frozen=True, slots=True)
class FaultEffect:
    """What the active faults do to one servo at one instant.

    ``u_add`` adds to the valve command, ``u_replace`` (if not None) replaces it,
    ``sensor_bias_m`` biases the rod sensor, ``jammed`` freezes the rod,
    ``runaway_dir`` (+-1, 0 = none) drives the valve fully open, ``to_zero`` replaces the rod
    command by the neutral position.
    """

    u_add: float = 0.0
    u_replace: float | None = None
    sensor_bias_m: float = 0.0
    jammed: bool = False
    runaway_dir: float = 0.0
    to_zero: bool = False


NO_FAULT = FaultEffect()


def fault_effect(faults: Sequence[ActuatorFault], surface: int, t_s: float) -> FaultEffect:
    """Combined effect of the faults on ``surface`` active at ``t_s`` (pure)."""
    u_add = 0.0
    u_rep: float | None = None
    bias = 0.0
    jammed = False
    run = 0.0
    to_zero = False
    any_active = False
    for f in faults:
        if f.surface != surface or not f.active(t_s):
            continue
        if f.kind == "loss_of_effectiveness":  # aerodynamic, not the servo's (effectiveness())
            continue
        any_active = True
        tau = t_s - f.t_start_s
        if f.kind in ("liquid_ofc", "solid_ofc"):
            s = f.amplitude * math.sin(2.0 * math.pi * f.frequency_hz * tau + f.phase_rad)
            if f.kind == "liquid_ofc":
                u_add += s
            else:
                u_rep = s
        elif f.kind == "liquid_jam":
            bias += f.amplitude
        elif f.kind == "solid_jam":
            jammed = True
        elif f.kind == "stuck_at_zero":
            to_zero = True
        else:  # runaway
            run = -1.0 if f.amplitude < 0.0 else 1.0
    if not any_active:
        return NO_FAULT
    return FaultEffect(u_add, u_rep, bias, jammed, run, to_zero)


def effectiveness(faults: Sequence[ActuatorFault], actuator: int, t_s: float) -> float:
    """Share of its nominal effect the actuator (surface deflection, or engine thrust) has at
    ``t_s``: ``1 - amplitude`` of an active loss of effectiveness, 0 with the engine out."""
    eff = 1.0
    for f in faults:
        if f.surface != actuator or not f.active(t_s):
            continue
        if f.kind == "loss_of_effectiveness":
            eff *= 1.0 - f.amplitude
        elif f.kind == "engine_out":
            eff = 0.0
    return eff


def apply_to_valve(u: float, eff: FaultEffect) -> float:
    """Valve command after input faults and runaway (Lu2017 eq. 4: ``u + f^i``)."""
    if eff.runaway_dir != 0.0:
        return eff.runaway_dir
    if eff.u_replace is not None:
        return eff.u_replace
    return u + eff.u_add
