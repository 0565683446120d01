"""Chen2020 sec. IV sliding-mode controller in the simulator: sliding on the linear model,
step tracking of roll and sideslip, the 6-DOF aircraft in a turn, and the PID default."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from gcs_monitor.evaluation.papers.chen2020_design import SmcFactory, make_smc
from gcs_monitor.families.yaw_rate.design import load_design
from sim_vehicle.autopilot.loops import Autopilot
from sim_vehicle.autopilot.smc_lateral import LateralSmc, SmcAutopilot, SmcGains
from sim_vehicle.physics import InitialCondition, ManoeuvreConfig, Simulation, WindConfig

DESIGN = load_design("transport")
EAS_MPS = 120.0
DT_S = 0.01


@pytest.fixture(scope="module")
def gains() -> SmcGains:
    return make_smc(DESIGN)[0]


def _linear_flight(gains: SmcGains, R_c: np.ndarray, t_end_s: float, *,
                   side_force: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """The SMC on the LPV model at one speed (noise-free, Euler at 100 Hz): (x, ||s||) per
    step. ``side_force=False``: without the rudder's side force in the sideslip row, the one
    term of the model that does not factor as B_v B_2 (eq. 29)."""
    A, B, _ = DESIGN.model.matrices(EAS_MPS)
    if not side_force:
        B = B.copy()
        B[1] = 0.0
    max_u = (10.0, 10.0)
    smc = LateralSmc(DESIGN.model, gains, max_u)
    x = np.zeros(4)
    xs, ss = [], []
    for _ in range(round(t_end_s / DT_S)):
        u = smc.update(x, EAS_MPS, R_c, DT_S)
        x = x + DT_S * (A @ x + B @ u)
        xs.append(x.copy())
        ss.append(float(np.linalg.norm(smc.s)))
    return np.array(xs), np.array(ss)


def test_steps_in_roll_and_sideslip_converge_on_the_linear_model(gains: SmcGains) -> None:
    """A 5 deg bank and a -1 deg sideslip command together: both tracked without offset
    (integral action, eq. 25), the switching function near zero throughout (the reference is
    pre-filtered, eq. 26, so the reaching phase is short) and zero at the end."""
    R_c = np.radians([5.0, -1.0])
    x, s = _linear_flight(gains, R_c, 30.0)
    np.testing.assert_allclose(x[-1, :2], R_c, atol=np.radians(0.01))
    # steady (a banked turn: the yaw rate of the turn stays, the state no longer moves)
    np.testing.assert_allclose(x[-1], x[-101], atol=1e-6)
    assert np.max(s) < 0.02  # rad/s
    # the rudder's side force (left out of B_c) holds s^ off zero by its share, no more
    assert s[-1] < 1e-3
    x, s = _linear_flight(gains, R_c, 30.0, side_force=False)
    np.testing.assert_allclose(x[-1, :2], R_c, atol=np.radians(0.01))
    assert s[-1] < 1e-9  # the model factors exactly: ideal sliding


def test_switching_function_obeys_its_reaching_law(gains: SmcGains) -> None:
    """On the model the controller was designed on, s^' = Phi s^ + v~_n (eq. 43 with xi = 0,
    e~_1 = 0): from an initial offset ||s^|| falls at least as fast as exp(Phi t)."""
    A, B, _ = DESIGN.model.matrices(EAS_MPS)
    smc = LateralSmc(DESIGN.model, gains, (10.0, 10.0))
    x = np.array([0.0, 0.0, 0.02, -0.01])  # a rate offset: s^ = [p, r] != 0
    s0 = None
    for _ in range(100):  # 1 s
        u = smc.update(x, EAS_MPS, np.zeros(2), DT_S)
        s0 = float(np.linalg.norm(smc.s)) if s0 is None else s0
        x = x + DT_S * (A @ x + B @ u)
    rate = -float(np.max(np.linalg.eigvals(gains.Phi).real))
    assert float(np.linalg.norm(smc.s)) <= s0 * math.exp(-rate * 0.99) * 1.05


def test_saturation_freezes_the_integrators(gains: SmcGains) -> None:
    """Conditional integration (ours): with the surfaces held at a small limit the integral
    states do not move."""
    smc = LateralSmc(DESIGN.model, gains, (1e-4, 1e-4))
    for _ in range(200):
        smc.update(np.array([0.1, 0.02, 0.0, 0.0]), EAS_MPS, np.zeros(2), DT_S)
        assert smc.saturated
    np.testing.assert_array_equal(smc.x_r, 0.0)


def test_six_dof_turn_slides_and_tracks(gains: SmcGains) -> None:
    """The 6-DOF transport in calm air, a 15 deg coordinated turn flown by the SMC: bank
    reached without offset, sideslip near zero, ||s^|| small once the turn is established."""
    turn = ManoeuvreConfig(kind="coordinated_turn", start_s=2.0, amplitude=math.radians(15.0))
    sim = Simulation("transport", InitialCondition(alt_m=1500.0), WindConfig(), turn, seed=3)
    sim.autopilot = SmcFactory(DESIGN.model, gains)(sim)
    assert isinstance(sim.autopilot, SmcAutopilot)
    phi, beta, s = [], [], []
    for _ in range(round(40.0 / sim.dt_s)):
        st = sim.step()
        phi.append(st.euler_rad[0])
        beta.append(st.ssa_rad)
        s.append(float(np.linalg.norm(sim.autopilot.smc.s)))
    late = slice(round(30.0 / sim.dt_s), None)
    np.testing.assert_allclose(np.array(phi)[late], math.radians(15.0), atol=math.radians(0.3))
    np.testing.assert_allclose(np.array(beta)[late], 0.0, atol=math.radians(0.2))
    assert max(s[late]) < 0.005


def test_the_pid_autopilot_stays_the_default() -> None:
    """Nothing selects the SMC unless asked: a Simulation flies the PID loops, and a study that
    sets it changes only its own simulation."""
    a = Simulation("transport", seed=1)
    assert type(a.autopilot) is Autopilot
    b = Simulation("transport", seed=1)
    assert type(b.autopilot) is Autopilot
    for _ in range(200):
        sa, sb = a.step(), b.step()
    np.testing.assert_array_equal(sa.surf_cmd_rad, sb.surf_cmd_rad)


def test_gains_round_trip_and_validation(gains: SmcGains) -> None:
    g2 = SmcGains.from_dict(gains.to_dict())
    np.testing.assert_array_equal(g2.N, gains.N)
    assert g2.prefilter_s == gains.prefilter_s and g2.modulation == gains.modulation
    with pytest.raises(ValueError):
        dataclasses.replace(gains, prefilter_s=(1.0,))
    with pytest.raises(ValueError):
        dataclasses.replace(gains, N=np.zeros((2, 3)))
