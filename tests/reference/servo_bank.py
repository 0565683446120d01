"""Plain-float reference of the servo-bank kernels (Lu2017 eqs. 4-13;
``sim_vehicle/actuators/_servo_jit.py``).

:func:`make_deriv` is the closure ``ServoBank`` evaluated in Python before it ran only the
kernels (all constants bound), :func:`rk4_bank_step` its RK4 step with the mechanical stop and
:func:`jam_step` the jammed surface.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from gcs_monitor.models.servo import ServoLoopParams, ServoParams, stalled_pressure
from sim_vehicle.actuators.faults import ActuatorFault, FaultEffect, apply_to_valve, fault_effect

Deriv = Callable[..., tuple[float, float, float, float, float, float]]


def make_deriv(p: ServoParams, lp: ServoLoopParams) -> Deriv:
    """``(x1, x2, x3, r, r', r'', q_com, bias, effect) -> derivative``: Lu2017 eq. 4 (plant),
    eq. 13 (NDI law on the biased rod sensor, eq. 5), the valve faults and the reference model.
    """
    a = p.piston_area_m2
    aps = a * p.supply_pressure_pa
    bb = p.damping_nspm
    inv_m = 1.0 / p.moving_mass_kg
    vmax = p.max_valve_flow_m3ps / a
    leak = p.leakage_mps
    vm = p.mean_chamber_volume_m3
    cnum = 2.0 * a * p.bulk_modulus_pa * vm / p.supply_pressure_pa
    vm2 = vm * vm
    a2 = a * a
    w = lp.ref_bandwidth_radps
    z2 = 2.0 * lp.ref_damping + 1.0
    w3, z2w2, z2w = w * w * w, z2 * w * w, z2 * w
    lam = lp.ndi_pole_radps
    k2, k1, k0 = 3.0 * lam, 3.0 * lam * lam, lam * lam * lam
    umax = lp.max_valve_cmd
    sqrt = math.sqrt

    def deriv(x1, x2, x3, r, rd, rdd, q_com, bias, eff):  # type: ignore[no-untyped-def]
        rddd = w3 * (q_com - r) - z2w2 * rd - z2w * rdd
        y = x1 + bias
        ydd = (aps * x3 - bb * x2) * inv_m
        cy = cnum / (vm2 - a2 * y * y)
        lf3h = (aps * cy * (-leak * x3 - x2) - bb * ydd) * inv_m
        num = rddd + k2 * (rdd - ydd) + k1 * (rd - x2) + k0 * (r - y) - lf3h
        sg = 1.0 if num >= 0.0 else -1.0
        arg = 1.0 - sg * x3
        u = num / (aps * inv_m * cy * vmax * sqrt(arg if arg > 1.0e-6 else 1.0e-6))
        u = umax if u > umax else (-umax if u < -umax else u)
        if eff is not None:
            u = apply_to_valve(u, eff)
        sg = 1.0 if u >= 0.0 else -1.0
        arg = 1.0 - sg * x3
        flow = vmax * (sqrt(arg) if arg > 0.0 else 0.0) * u
        x3d = cnum / (vm2 - a2 * x1 * x1) * (flow - leak * x3 - x2)
        return x2, ydd, x3d, rd, rdd, rddd

    return deriv


def rk4_bank_step(deriv: Deriv, p: ServoParams, faults: tuple[ActuatorFault, ...],
                  stroke_m: float, gain_radpm: float, x: list[list[float]], t_s: float,
                  dt_s: float, cmd: tuple[float, ...]) -> None:
    """One bank step of the surfaces that are not jammed (``x`` in place): RK4 with the command
    and the fault effect held, then the mechanical stop."""
    for i in range(len(x)):
        q_com = max(-stroke_m, min(stroke_m, cmd[i] / gain_radpm))
        eff = fault_effect(faults, i, t_s) if any(f.surface == i for f in faults) else None
        bias = eff.sensor_bias_m if eff is not None else 0.0
        s = x[i]
        k1 = deriv(*s, q_com, bias, eff)
        k2 = deriv(*(a + 0.5 * dt_s * b for a, b in zip(s, k1, strict=True)), q_com, bias, eff)
        k3 = deriv(*(a + 0.5 * dt_s * b for a, b in zip(s, k2, strict=True)), q_com, bias, eff)
        k4 = deriv(*(a + dt_s * b for a, b in zip(s, k3, strict=True)), q_com, bias, eff)
        for j in range(6):
            s[j] = s[j] + dt_s / 6.0 * (k1[j] + 2.0 * (k2[j] + k3[j]) + k4[j])
        if abs(s[0]) > stroke_m:
            s[0] = math.copysign(stroke_m, s[0])
            s[1] = 0.0
            u_end = eff.runaway_dir if eff is not None else 0.0
            if u_end * s[0] > 0.0:
                s[2] = stalled_pressure(u_end, p)


def jam_step(deriv: Deriv, s: list[float], q_com: float, eff: FaultEffect, dt_s: float,
             jam_pos: float) -> None:
    """A jammed surface (``s`` in place): rod frozen, the reference model by explicit Euler."""
    k1 = deriv(*s, q_com, eff.sensor_bias_m, eff)
    s[3] += dt_s * k1[3]
    s[4] += dt_s * k1[4]
    s[5] += dt_s * k1[5]
    s[0] = jam_pos
    s[1] = 0.0
