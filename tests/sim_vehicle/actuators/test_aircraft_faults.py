"""Aircraft-level actuator faults (issue 17): stuck at zero, loss of effectiveness, engine out,
as the servo bank and the physics apply them, and the seeded ``actuators`` campaign set."""

from __future__ import annotations

import math

import pytest

from sim_vehicle.actuators.campaign import servo_campaign
from sim_vehicle.actuators.faults import ENGINE, SERVO_FAULT_KINDS, ActuatorFault, effectiveness
from sim_vehicle.actuators.servo_bank import ActuatorGeometry, ServoBank
from sim_vehicle.campaigns import ACTUATOR_CASES, generate_set
from sim_vehicle.physics import Simulation
from sim_vehicle.scenario import ScenarioError, parse_scenario, to_toml

GEO = ActuatorGeometry(rod_gain_radpm=5.0, rod_stroke_m=0.1)
DT = 0.01


def _hold(bank: ServoBank, cmd: tuple[float, float, float], t0: float, t1: float) -> None:
    t = t0
    while t < t1 - 1e-9:
        bank.step(t, DT, cmd)
        t += DT


def test_stuck_at_zero_drives_the_surface_to_neutral_and_holds_it() -> None:
    f = ActuatorFault(surface=0, kind="stuck_at_zero", t_start_s=1.0)
    bank = ServoBank(GEO, (0.0, 0.0, 0.0), faults=(f,))
    _hold(bank, (0.2, 0.0, 0.0), 0.0, 1.0)
    assert bank.deflection_rad(0) > 0.19  # healthy: follows the command
    _hold(bank, (0.2, 0.0, 0.0), 1.0, 2.0)
    assert abs(bank.deflection_rad(0)) < 1e-3  # rad: neutral within the servo's settling
    _hold(bank, (-0.3, 0.0, 0.0), 2.0, 3.0)
    assert abs(bank.deflection_rad(0)) < 1e-3
    assert bank.cmd_rad[0] == -0.3  # the autopilot's command is still what it sent


def test_effectiveness_by_hand() -> None:
    loe = ActuatorFault(surface=2, kind="loss_of_effectiveness", t_start_s=5.0, amplitude=0.6)
    out = ActuatorFault(surface=ENGINE, kind="engine_out", t_start_s=7.0, t_end_s=9.0)
    faults = (loe, out)
    assert effectiveness(faults, 2, 4.99) == 1.0
    assert math.isclose(effectiveness(faults, 2, 5.0), 0.4)
    assert effectiveness(faults, 0, 6.0) == 1.0  # another surface
    assert effectiveness(faults, ENGINE, 8.0) == 0.0
    assert effectiveness(faults, ENGINE, 9.0) == 1.0  # ended


@pytest.mark.parametrize(("surface", "kind", "amp"), [
    (ENGINE, "solid_jam", 0.0), (0, "engine_out", 0.0), (1, "loss_of_effectiveness", 1.5)])
def test_invalid_actuator_faults_are_rejected(surface: int, kind: str, amp: float) -> None:
    with pytest.raises(ValueError):
        ActuatorFault(surface=surface, kind=kind, amplitude=amp)


def test_scenario_reads_engine_and_loss_of_effectiveness() -> None:
    text = """
[scenario]
airframe = "uav"
duration_s = 2.0
[[actuator_faults]]
surface = "engine"
kind = "engine_out"
t_start_s = 1.0
[[actuator_faults]]
surface = "rudder"
kind = "loss_of_effectiveness"
amplitude = 0.5
"""
    sc = parse_scenario(text)
    assert [(f.surface, f.kind, f.amplitude) for f in sc.actuator_faults] == [
        (ENGINE, "engine_out", 0.0), (2, "loss_of_effectiveness", 0.5)]
    assert parse_scenario(to_toml(sc)).actuator_faults == sc.actuator_faults
    with pytest.raises(ScenarioError, match="engine"):
        parse_scenario(text.replace('"engine_out"', '"solid_jam"'))


def test_engine_out_loses_thrust_and_surface_loss_only_aerodynamic() -> None:
    faults = (ActuatorFault(ENGINE, "engine_out", 0.5),
              ActuatorFault(1, "loss_of_effectiveness", 0.5, amplitude=0.5))
    sim = Simulation("uav", actuator_faults=faults, seed=1)
    healthy = Simulation("uav", seed=1)
    for _ in range(150):
        st = sim.step()
        hs = healthy.step()
    assert st.throttle < 0.05 < hs.throttle  # engine state: no thrust whatever the command
    assert st.throttle_cmd > hs.throttle_cmd  # the autopilot asks for more
    assert st.tas_mps < hs.tas_mps - 2.0
    assert st.effectiveness is not None and list(st.effectiveness) == [1.0, 0.5, 1.0, 0.0]
    # the elevator still moves as commanded (its loss is aerodynamic): SURF shows no fault
    assert abs(st.surf_pos_rad[1] - st.surf_cmd_rad[1]) < 0.05  # rad: servo lag at full throw
    assert st.att_cmd_rad is not None and st.rate_cmd_radps is not None


def test_actuator_campaign_is_seeded_and_covers_every_case() -> None:
    a = generate_set("actuators", 15, seed=3)
    b = generate_set("actuators", 15, seed=3)
    assert [to_toml(s) for s in a] == [to_toml(s) for s in b]
    cases = {(f.surface, f.kind) for s in a for f in s.actuator_faults}
    assert cases == set(ACTUATOR_CASES)
    assert sum(not s.actuator_faults for s in a) == 4  # 30 % fault-free, evenly spread
    assert all(s.wind.kind == "turbulence" and s.manoeuvre.kind != "level" for s in a)
    ff = generate_set("actuators_fault_free", 5, seed=3)
    assert not any(s.actuator_faults for s in ff)


def test_servo_campaign_draws_only_lu2017_cases() -> None:
    """The servo campaign cycles through Lu2017's five cases, never the aircraft-level kinds
    the simulator also flies (those have no servo-level signature to score)."""
    runs = servo_campaign(30, seed=0)
    kinds = [f.kind for s in runs for f in s.actuator_faults]
    assert set(kinds) == set(SERVO_FAULT_KINDS)
    assert sum(not s.actuator_faults for s in runs) == 9  # 30 % fault-free
