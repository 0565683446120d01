"""The three control-surface servos (aileron, elevator, rudder), each a Lu2017 hydraulic actuator.

Each surface: commanded deflection -> rod command ``q_com = delta_cmd / rod_gain_radpm`` ->
third-order reference model -> NDI valve law -> hydraulic plant (Lu2017 eqs. 4-13) ->
rod position -> deflection ``delta = rod_gain_radpm * x1`` (a linear lever, the gain comes
from the airframe file). The rod travel is limited by mechanical stops at ``+-rod_stroke_m``.

Per surface the state is ``[x1, x2, x3, r, r', r'']`` (plant + reference model), integrated
with RK4 over the simulation step with the command and the fault effect held.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from gcs_monitor.models.servo import ServoLoopParams, ServoParams, stalled_pressure
from sim_vehicle.actuators import _servo_jit as _sj
from sim_vehicle.actuators.faults import ActuatorFault, apply_to_valve, fault_effect

N_SURFACES = 3


@dataclass(frozen=True, slots=True)
class ActuatorGeometry:
    """Rod-to-surface lever of one airframe (from its TOML ``[actuators]`` table)."""

    rod_gain_radpm: float  # deflection per rod displacement, rad/m
    rod_stroke_m: float  # mechanical stop, |x1| <= stroke


class ServoBank:
    """Stateful bank of three servos; ``step`` advances them by ``dt_s``."""

    def __init__(
        self,
        geometry: ActuatorGeometry,
        init_defl_rad: Sequence[float],
        *,
        faults: Sequence[ActuatorFault] = (),
        params: ServoParams | None = None,
        loop: ServoLoopParams | None = None,
    ) -> None:
        self.geo = geometry
        self.p = params if params is not None else ServoParams()
        self.lp = loop if loop is not None else ServoLoopParams()
        self.faults = tuple(faults)
        self._faulted = tuple(any(f.surface == i for f in self.faults) for i in range(N_SURFACES))
        rows = []
        for d in init_defl_rad:
            q0 = d / geometry.rod_gain_radpm
            rows.append([q0, 0.0, 0.0, q0, 0.0, 0.0])
        self.x = np.array(rows, dtype=float)  # (3, 6) state per surface
        self._rod: list[float] = self.x[:, 0].tolist()  # x1 per surface as floats (outputs)
        self.cmd_rad = [float(d) for d in init_defl_rad]
        self.sensor_bias_m = [0.0] * N_SURFACES
        self._jam_pos: list[float | None] = [None] * N_SURFACES
        self._f = self._make_deriv()
        self._prm = _sj.pack_params(self.p, self.lp, geometry.rod_stroke_m)
        self._inp = np.zeros((N_SURFACES, _sj.N_IN))
        self._inp_faults = [False] * N_SURFACES  # fault columns of the row not yet cleared

    # ------------------------------------------------------------------ derivative
    def _make_deriv(self) -> Callable[..., tuple[float, float, float, float, float, float]]:
        """Closure evaluating Lu2017 eqs. 4, 13 and the reference model with all constants bound.

        Same equations as :func:`gcs_monitor.models.servo.servo_derivative`,
        :func:`~gcs_monitor.models.servo.ndi_control` and
        :func:`~gcs_monitor.models.servo.reference_model_derivative` (a test checks they
        agree). The compiled RK4 (``_servo_jit``) is this closure written for numba; the
        closure itself serves the jam path and the tests.
        """
        p = self.p
        lp = self.lp
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

    def step(self, t_s: float, dt_s: float, cmd_rad: Sequence[float]) -> None:
        """Advance all servos from ``t_s`` to ``t_s + dt_s`` with the commands held.

        A jammed surface is handled here; the others go through the compiled RK4
        (:func:`sim_vehicle.actuators._servo_jit.step_bank`, same equations as :meth:`_make_deriv`).
        """
        stroke = self.geo.rod_stroke_m
        gain = self.geo.rod_gain_radpm
        inp = self._inp
        for i in range(N_SURFACES):
            c = cmd_rad[i]
            self.cmd_rad[i] = c
            q_com = max(-stroke, min(stroke, c / gain))
            eff = fault_effect(self.faults, i, t_s) if self._faulted[i] else None
            self.sensor_bias_m[i] = eff.sensor_bias_m if eff is not None else 0.0
            row = inp[i]
            if eff is not None and eff.jammed:
                s = self.x[i]
                if self._jam_pos[i] is None:
                    self._jam_pos[i] = float(s[0])
                # Surface mechanically stuck: rod frozen; the reference model keeps running.
                k1 = self._f(*s.tolist(), q_com, eff.sensor_bias_m, eff)
                s[3] += dt_s * k1[3]
                s[4] += dt_s * k1[4]
                s[5] += dt_s * k1[5]
                s[0] = self._jam_pos[i]
                s[1] = 0.0
                row[_sj.I_ACTIVE] = 0.0
                continue
            self._jam_pos[i] = None
            row[_sj.I_ACTIVE] = 1.0
            row[_sj.I_Q_COM] = q_com
            row[_sj.I_BIAS] = self.sensor_bias_m[i]
            if eff is not None:
                row[_sj.I_EFF] = 1.0
                row[_sj.I_RUNAWAY] = eff.runaway_dir
                row[_sj.I_HAS_REP] = 0.0 if eff.u_replace is None else 1.0
                row[_sj.I_REP] = 0.0 if eff.u_replace is None else eff.u_replace
                row[_sj.I_ADD] = eff.u_add
                row[_sj.I_STALL_P] = stalled_pressure(eff.runaway_dir, self.p)
                self._inp_faults[i] = True
            elif self._inp_faults[i]:
                row[_sj.I_EFF] = 0.0
                self._inp_faults[i] = False
        _sj.step_bank(self.x, inp, dt_s, self._prm)
        self._rod = self.x[:, 0].tolist()

    # ------------------------------------------------------------------ outputs
    def deflection_rad(self, i: int) -> float:
        return self.geo.rod_gain_radpm * self._rod[i]

    def rod_sensor_m(self, i: int) -> float:
        """Rod position sensor (Lu2017 eq. 5: x1 + f^o)."""
        return self._rod[i] + self.sensor_bias_m[i]

    def rod_m(self, i: int) -> float:
        return self._rod[i]
