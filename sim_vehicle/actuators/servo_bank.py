"""The three control-surface servos (aileron, elevator, rudder), each a Lu2017 hydraulic actuator.

Each surface: commanded deflection -> rod command ``q_com = delta_cmd / rod_gain_radpm`` ->
third-order reference model -> NDI valve law -> hydraulic plant (Lu2017 eqs. 4-13) ->
rod position -> deflection ``delta = rod_gain_radpm * x1`` (a linear lever, the gain comes
from the airframe file). The rod travel is limited by mechanical stops at ``+-rod_stroke_m``.

Per surface the state is ``[x1, x2, x3, r, r', r'']`` (plant + reference model), integrated
with RK4 over the simulation step with the command and the fault effect held. The equations
run in the numba kernels of ``_servo_jit.py`` (their one implementation); the plain-float
reference of the equivalence test is ``tests/reference/servo_bank.py``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from gcs_monitor.core.kernels import load_kernels
from gcs_monitor.models.servo import ServoLoopParams, ServoParams, stalled_pressure
from sim_vehicle.actuators.faults import ActuatorFault, fault_effect

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
        self._sj = _sj = load_kernels("sim_vehicle.actuators._servo_jit")
        self._prm = _sj.pack_params(self.p, self.lp, geometry.rod_stroke_m)
        self._inp = np.zeros((N_SURFACES, _sj.N_IN))
        self._inp_faults = [False] * N_SURFACES  # fault columns of the row not yet cleared

    def step(self, t_s: float, dt_s: float, cmd_rad: Sequence[float]) -> None:
        """Advance all servos from ``t_s`` to ``t_s + dt_s`` with the commands held.

        A jammed surface goes through ``_servo_jit.jam_step``, the others through the RK4 of
        ``_servo_jit.step_bank``.
        """
        _sj = self._sj
        stroke = self.geo.rod_stroke_m
        gain = self.geo.rod_gain_radpm
        inp = self._inp
        for i in range(N_SURFACES):
            c = cmd_rad[i]
            self.cmd_rad[i] = c
            q_com = max(-stroke, min(stroke, c / gain))
            eff = fault_effect(self.faults, i, t_s) if self._faulted[i] else None
            if eff is not None and eff.to_zero:
                q_com = 0.0  # stuck at zero: the servo holds neutral whatever is commanded
            self.sensor_bias_m[i] = eff.sensor_bias_m if eff is not None else 0.0
            row = inp[i]
            if eff is not None and eff.jammed:
                s = self.x[i]
                jam = self._jam_pos[i]
                if jam is None:
                    jam = self._jam_pos[i] = float(s[0])
                # Surface mechanically stuck: rod frozen; the reference model keeps running.
                _sj.jam_step(s, q_com, dt_s, self._prm, jam)
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
