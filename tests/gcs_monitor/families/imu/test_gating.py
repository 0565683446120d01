"""Input-validity term and GPS-velocity step gate (gcs_monitor/families/imu/gating.py)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from gcs_monitor.families.imu.gating import (
    GateConfig,
    GateDecision,
    MeasurementStepGate,
    intra_sample_input_var,
    step_bound,
)
from gcs_monitor.families.imu.imu_ts import FAULT_CHANNELS, ImuTsConfig, ImuTwoStageEstimator
from tests.helpers.imu_synth import FAULT_START_S, make_run


def test_intra_sample_variance_of_a_step_equals_its_formula() -> None:
    # a 60 m/s^2 catapult step inside one sample: Delta^2 u = 60 on x, nothing on y, z
    u0 = np.array([0.0, 0.0, -9.8])
    u2 = np.array([60.0, 0.0, -9.8])
    sigma = np.full(3, 0.1)
    var = intra_sample_input_var(u0, u0, u2, sigma, 3.0, timing=False)
    expected_x = ((60.0 - 3.0 * math.sqrt(6.0) * 0.1) / 2.0) ** 2  # hand: (59.265 / 2)^2
    np.testing.assert_allclose(var, [expected_x, 0.0, 0.0], rtol=1e-12)
    # with the sample-timing term the first difference (60 too) has the lower floor
    # 3 sqrt(2) sigma, so it is the larger: (59.576 / 2)^2
    var = intra_sample_input_var(u0, u0, u2, sigma, 3.0)
    expected_x = ((60.0 - 3.0 * math.sqrt(2.0) * 0.1) / 2.0) ** 2
    np.testing.assert_allclose(var, [expected_x, 0.0, 0.0], rtol=1e-12)


def test_intra_sample_variance_of_a_ramp_and_of_noise_level_changes() -> None:
    # a ramp (any slope) is exactly what the first-order hold integrates for instantaneous
    # samples: no step term; whether a sample is the instant or the interval mean is not known,
    # so the timing term covers half a sample of it: ((slope - 3 sqrt(2) sigma) / 2)^2
    ramp = [np.full(3, a) for a in (1.0, 3.0, 5.0)]
    assert not intra_sample_input_var(*ramp, np.full(3, 0.01), 3.0, timing=False).any()
    np.testing.assert_allclose(intra_sample_input_var(*ramp, np.full(3, 0.01), 3.0),
                               np.full(3, ((2.0 - 3.0 * math.sqrt(2.0) * 0.01) / 2.0) ** 2),
                               rtol=1e-12)
    # first and second differences within their 3-sigma floors are noise
    rng = np.random.default_rng(3)
    sigma = np.full(3, 0.05)
    u = rng.standard_normal((2000, 3)) * sigma
    n_hit = sum(intra_sample_input_var(u[k - 2], u[k - 1], u[k], sigma, 3.0).any()
                for k in range(2, len(u)))
    assert n_hit < 0.04 * len(u)  # P(|N| > 3 sigma) = 0.27 % per channel and difference


def test_velocity_step_bound_equals_its_formula() -> None:
    cfg = GateConfig(gate_sigma=3.0, acc_fault_step_max_mps2=15.0)
    s = np.array([1e-4, 2e-4, 3e-4])
    extra = np.array([4.0, 0.0, 1.0])
    dt = 0.02
    expected = 3.0 * math.sqrt(2.0 * 6e-4 + dt * dt * 5.0) + dt * 15.0
    assert step_bound(s, extra, dt, cfg.gate_sigma, cfg.acc_fault_step_max_mps2) \
        == pytest.approx(expected, rel=1e-12)


def test_gate_rejects_a_persistent_step_then_reanchors() -> None:
    g = MeasurementStepGate(GateConfig())
    bound = 0.3
    # consistent manoeuvre: innovations and increments small
    for _ in range(5):
        assert g.decide(np.array([0.01, -0.01, 0.0]), np.zeros(3), bound) is GateDecision.ACCEPT
    # reference jumps 1 m/s north: increment mismatch 1 m/s > bound
    assert g.decide(np.array([1.0, 0.0, 0.0]), np.zeros(3), bound) is GateDecision.REJECT
    # next sample: still 1 m/s off the state, but the increment is consistent -> a step
    assert g.decide(np.array([1.01, 0.0, 0.0]), np.array([1.0, 0.0, 0.0]), bound) \
        is GateDecision.REANCHOR
    assert not g.pending


def test_gate_accepts_the_sample_after_a_spike() -> None:
    g = MeasurementStepGate(GateConfig())
    assert g.decide(np.array([0.0, 2.0, 0.0]), np.zeros(3), 0.3) is GateDecision.REJECT
    assert g.decide(np.array([0.0, 0.02, 0.0]), np.array([0.0, 2.0, 0.0]), 0.3) \
        is GateDecision.ACCEPT


def test_gate_reanchors_after_max_rejected_samples() -> None:
    g = MeasurementStepGate(GateConfig(max_rejected_n=3))
    nu = np.zeros(3)
    decisions = []
    for k in range(4):  # a mismatch that keeps growing by 1 m/s per sample
        r_prev = nu.copy()
        nu = np.array([float(k + 1), 0.0, 0.0])
        decisions.append(g.decide(nu, r_prev, 0.3))
    assert decisions == [GateDecision.REJECT] * 3 + [GateDecision.REANCHOR]


def _track(est: ImuTwoStageEstimator, frames: list) -> tuple[np.ndarray, list[str]]:
    out, why = [], []
    for fr in frames:
        e = est.step(fr)
        assert e.available and e.numerics_ok
        out.append([e.faults[c] for c in FAULT_CHANNELS])
        why.append(e.reinit)
    return np.array(out), why


def test_estimator_reanchors_on_a_velocity_step_and_keeps_its_fault_estimates() -> None:
    run = make_run(np.random.default_rng(1), duration_s=20.0, faults=False)
    step_at = 8.0
    frames = []
    for fr in run.frames:
        if fr.t_us * 1e-6 >= step_at:  # an estimator reset: +1.5 m/s north from here on
            fr = dataclasses.replace(fr, gps_vel_ned_mps=fr.gps_vel_ned_mps + [1.5, 0.0, 0.0])
        frames.append(fr)
    t = run.t_s
    after = (t > step_at) & (t < step_at + 3.0)
    f_gate, why = _track(ImuTwoStageEstimator(ImuTsConfig()), frames)
    f_plain, _ = _track(ImuTwoStageEstimator(ImuTsConfig(gate=dataclasses.replace(
        ImuTsConfig().gate, enabled=False))), frames)
    reinits = [(t[k], w) for k, w in enumerate(why) if w and w != "start"]
    assert len(reinits) == 1 and abs(reinits[0][0] - step_at) < 0.05, reinits
    assert "gps velocity step 1.5" in reinits[0][1]
    # without the gate the step is absorbed as an accelerometer fault; with it the fault
    # estimates stay at the level of the same run without the step (max over the 3 s)
    f_clean, _ = _track(ImuTwoStageEstimator(ImuTsConfig()), run.frames)
    assert np.abs(f_plain[after, 0]).max() > 0.5
    assert np.abs(f_gate[after, :3]).max() < 1.5 * np.abs(f_clean[after, :3]).max() + 0.01


def test_gate_lets_the_lu2016_table2_faults_through() -> None:
    run = make_run(np.random.default_rng(1), duration_s=20.0)
    f_hat, why = _track(ImuTwoStageEstimator(ImuTsConfig()), run.frames)
    assert [w for w in why if w] == ["start"]  # no sample gated: faults are not glitches
    late = (run.t_s > FAULT_START_S + 2.0)
    np.testing.assert_allclose(f_hat[late, 0].mean(), 3.0, atol=0.05)  # the 3 m/s^2 bias


def test_heading_wrap_is_not_an_attitude_step() -> None:
    # the default synthetic run starts near psi = +pi and wraps (tests/helpers/imu_synth.py)
    run = make_run(np.random.default_rng(2), duration_s=20.0, faults=False)
    psi = np.array([fr.euler_rad[2] for fr in run.frames])
    assert np.any(np.abs(np.diff(psi)) > math.pi)  # the measured heading does wrap
    est = ImuTwoStageEstimator(ImuTsConfig())
    for fr in run.frames:
        est.step(fr)
        assert not est._gates[1].pending  # never a rejected attitude sample
