"""Manoeuvre scripts and autopilot loops."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim_vehicle.autopilot.loops import Feedback, Targets
from sim_vehicle.autopilot.manoeuvres import ManoeuvreScript, ManoeuvreSpec
from sim_vehicle.dynamics.airframe import load_airframe
from sim_vehicle.physics import InitialCondition, ManoeuvreConfig, Simulation

GAINS = load_airframe("uav").autopilot
FB = Feedback(
    alt_m=1000.0,
    vd_mps=0.0,
    tas_mps=25.0,
    rho_kgpm3=1.1,
    phi=0.0,
    theta=0.05,
    psi=0.0,
    p=0.0,
    q=0.0,
    r=0.0,
    beta=0.0,
    acc_z_mps2=-9.8,
    gamma_rad=0.0,
)


def test_doublet_3211_sequence() -> None:
    spec = ManoeuvreSpec(
        kind="doublet_3211", start_s=10.0, amplitude=0.02, surface="aileron", period_s=1.0
    )
    m = ManoeuvreScript(spec, GAINS, 1000.0, 25.0, 0.0)
    seq = [m.targets(t, FB).surface_offset_rad[0] for t in np.arange(9.5, 18.0, 0.5)]
    # t: 9.5 | 10..12.5 (+) | 13..14.5 (-) | 15..15.5 (+) | 16..16.5 (-) | 17.. 0
    want = [0.0] + [0.02] * 6 + [-0.02] * 4 + [0.02] * 2 + [-0.02] * 2 + [0.0] * 2
    assert seq == pytest.approx(want)
    assert all(m.targets(12.0, FB).surface_offset_rad[i] == 0.0 for i in (1, 2))


def test_s_turn_phases_follow_chen2020() -> None:
    m = ManoeuvreScript(ManoeuvreSpec(kind="s_turn", start_s=0.0), GAINS, 1000.0, 25.0, 0.0)
    assert m.targets(5.0, FB).bank_rad == pytest.approx(math.radians(20.0))
    assert m.targets(15.0, FB).bank_rad == pytest.approx(math.radians(-20.0))
    assert m.targets(35.0, FB).beta_rad == pytest.approx(math.radians(-2.0))
    assert m.targets(45.0, FB).beta_rad == pytest.approx(math.radians(3.0))
    assert m.targets(55.0, FB).beta_rad == 0.0


def test_parabola_state_machine() -> None:
    m = ManoeuvreScript(ManoeuvreSpec(kind="parabolic", start_s=0.0), GAINS, 1000.0, 25.0, 0.0)
    g_e = GAINS.parabola_gamma_rad
    import dataclasses

    def fb(gamma: float) -> Feedback:
        return dataclasses.replace(FB, gamma_rad=gamma)

    assert m.targets(0.1, fb(0.0)).load_factor == pytest.approx(1.0 + GAINS.parabola_pull_g)
    assert m.targets(1.0, fb(g_e + 0.01)).load_factor == 0.0
    assert m.targets(2.0, fb(0.0)).load_factor == 0.0
    assert m.targets(3.0, fb(-g_e - 0.01)).load_factor == pytest.approx(1.0 + GAINS.parabola_pull_g)
    assert m.targets(4.0, fb(0.01)).load_factor is None  # back to altitude hold


def test_level_targets_are_the_initial_condition() -> None:
    m = ManoeuvreScript(ManoeuvreSpec(), GAINS, 1234.0, 25.0, 0.5)
    assert m.targets(100.0, FB) == Targets(1234.0, 25.0, 0.5)


def test_unknown_manoeuvre_is_rejected() -> None:
    with pytest.raises(ValueError, match="unknown manoeuvre"):
        ManoeuvreScript(ManoeuvreSpec(kind="loop"), GAINS, 1000.0, 25.0, 0.0)


def test_coordinated_turn_holds_bank_with_small_sideslip() -> None:
    sim = Simulation("uav", manoeuvre=ManoeuvreConfig(kind="coordinated_turn", start_s=1.0))
    for _ in range(2500):
        st = sim.step()
    assert abs(st.euler_rad[0] - math.radians(30.0)) < math.radians(2.0)
    assert abs(st.ssa_rad) < math.radians(1.0)
    assert abs(st.alt_m - 1000.0) < 3.0
    # turn rate of a coordinated turn: psi_dot = g tan(phi) / V (checked via body rates)
    psi_dot = (
        st.omega_frd_radps[1] * math.sin(st.euler_rad[0])
        + st.omega_frd_radps[2] * math.cos(st.euler_rad[0])
    ) / math.cos(st.euler_rad[1])
    assert psi_dot == pytest.approx(9.81 * math.tan(st.euler_rad[0]) / st.tas_mps, rel=0.05)


def test_climb_and_decel_reach_targets() -> None:
    sim = Simulation("uav", manoeuvre=ManoeuvreConfig(kind="climb", start_s=1.0, amplitude=50.0))
    for _ in range(4000):
        st = sim.step()
    assert abs(st.alt_m - 1050.0) < 2.0
    sim = Simulation(
        "uav",
        InitialCondition(),
        manoeuvre=ManoeuvreConfig(kind="decel", start_s=1.0, amplitude=4.0),
    )
    for _ in range(3000):
        st = sim.step()
    assert abs(st.tas_mps - 21.0) < 0.5 and abs(st.alt_m - 1000.0) < 3.0
