"""The yaw-rate family in the pipeline: coverage when an input is missing or the speed is
outside the model, the alarm and the corrected gyro on a yaw-rate bias (linear-model Frames)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from gcs_monitor.core.types import ChannelId
from gcs_monitor.families.base import FamilyContext
from gcs_monitor.families.yaw_rate import SPEC
from gcs_monitor.families.yaw_rate.config import YawRateFamilyConfig
from gcs_monitor.families.yaw_rate.family import YawRateFamily
from gcs_monitor.fdi.events import AlarmKind, AlarmState
from gcs_monitor.pipeline import VehiclePipeline
from gcs_monitor.telemetry.frame import Frame, ImuSample

CFG = YawRateFamilyConfig()
DEG = math.pi / 180
CH = ChannelId("gyro", 0, "r")


def _frames(n: int, *, eas: float = 120.0, bias_from_s: float = math.inf,
            bias_degps: float = 3.0, ssa: bool = True) -> tuple[list[Frame], np.ndarray]:
    """100 Hz Frames of the shipped transport model at ``eas`` (sea level: CAS = EAS) under a
    light roll / yaw loop and random surface excitation; a yaw-rate bias from ``bias_from_s``."""
    from gcs_monitor.families.yaw_rate.design import load_design

    model = load_design("transport").model
    A, B, _ = model.matrices(min(max(eas, model.eas_range_mps[0]), model.eas_range_mps[1]))
    rng = np.random.default_rng(11)
    dt = 0.01
    x = np.zeros(4)
    exc = np.zeros(2)
    frames, r_true = [], np.zeros(n)
    for k in range(n):
        t = k * dt
        if k % 300 == 0:
            exc = rng.normal(0.0, 0.01, 2)
        u = exc - np.array([0.5 * x[0] + 0.5 * x[2], -1.0 * x[3]])
        r_true[k] = x[3]
        r_meas = x[3] + (bias_degps * DEG if t >= bias_from_s else 0.0)
        t_us = round(t * 1e6)
        frames.append(Frame(
            t_us=t_us, imu=[ImuSample(t_us, 0, np.zeros(3), np.array([x[2], 0.0, r_meas]))],
            euler_rad=np.array([x[0], 0.0, 0.0]), att_age_s=0.0,
            ssa_rad=x[1] if ssa else math.nan, cas_mps=np.full(3, eas), cas_age_s=np.zeros(3),
            baro_alt_m=0.0, surf_pos_rad=np.array([u[0], 0.0, u[1]]), surf_age_s=0.0))
        x = x + dt * (A @ x + B @ u)
    return frames, r_true


def _run(frames: list[Frame]) -> tuple[VehiclePipeline, list, list]:
    fam = YawRateFamily(CFG, FamilyContext(vehicle=1, stale_after_s=0.5))
    p = VehiclePipeline(1, [fam])
    outs = [p.step(f) for f in frames]
    return p, [e for o in outs for e in o.events], outs


def test_registered_with_its_inputs() -> None:
    assert SPEC.name == "yaw_rate" and SPEC.config is YawRateFamilyConfig
    missing = SPEC.missing_inputs({"imu_instances": 1, "attitude": True, "ssa": False,
                                   "surfaces": True, "cas_instances": 3})
    assert missing == ["sideslip"]


def test_without_sideslip_the_family_is_unavailable_and_says_why() -> None:
    frames, _ = _frames(1500, ssa=False)
    p, events, outs = _run(frames)
    assert not events
    st = p.status["yaw_rate"]
    assert not st.judged and not st.inputs and st.reason == "no sideslip (AOA_SSA)"
    assert outs[-1].coverage[0].state == "unavailable"


def test_outside_the_models_speeds_it_does_not_judge() -> None:
    frames, _ = _frames(500, eas=30.0)
    p, events, _ = _run(frames)
    assert not events
    st = p.status["yaw_rate"]
    # the reason names the design whose speeds these are not (the transport's, 79-172 m/s EAS,
    # 5 % margin)
    assert not st.judged
    assert st.reason == "EAS below the 'transport' design's 75-181 m/s (its model holds only " \
        "there)"


def test_yaw_rate_bias_alarmed_and_corrected() -> None:
    frames, r_true = _frames(6000, bias_from_s=30.0)
    p, events, outs = _run(frames)
    raised = [e for e in events if e.state is AlarmState.RAISED]
    assert len(raised) == 1
    ev = raised[0]
    assert ev.channel == CH and ev.kind is AlarmKind.SENSOR_FAULT
    assert ev.estimator == "yaw_rate_smo"
    assert 30.0 < ev.t_us * 1e-6 < 32.0  # 1 s window, 80 % above 0.5 deg/s
    assert p.status["yaw_rate"].judged
    est = outs[-1].estimates[0]
    assert abs(est.faults[CH] - 3.0 * DEG) < 0.05 * DEG  # rad/s, linear model: exact in the end
    assert abs(est.virtual[CH] - r_true[-1]) < 0.05 * DEG  # the corrected gyro (eq. 24)


def test_two_families_alarming_one_channel_are_both_active() -> None:
    """imu_ts and yaw_rate_smo both judge gyro0.r: the health keeps each one's alarm until it
    clears."""
    from gcs_monitor.fdi.events import AlarmEvent, FaultType

    p = VehiclePipeline(1, [])

    def ev(t: int, est: str, state: AlarmState) -> AlarmEvent:
        return AlarmEvent(t_us=t, channel=CH, state=state, kind=AlarmKind.SENSOR_FAULT,
                          fault_type=FaultType.DRIFT, magnitude=0.1, residual_rms=0.1,
                          threshold=0.05, estimator=est, message="", vehicle=1)

    p.step(Frame(t_us=0, imu=[None]), [ev(0, "imu_ts", AlarmState.RAISED),
                                       ev(0, "yaw_rate_smo", AlarmState.RAISED)])
    p.step(Frame(t_us=10, imu=[None]), [ev(10, "yaw_rate_smo", AlarmState.CLEARED)])
    active = p.health()["active_alarms"]
    assert [(a["channel"], a["estimator"]) for a in active] == [(str(CH), "imu_ts")]


def test_a_short_gap_reanchors_without_losing_the_fault_or_judging() -> None:
    """1 s without Frames while a 3 deg/s bias is active: the observer restarts from the
    measurement corrected by its last estimate, so the estimate and the alarm carry on, and
    judging does not pause (no warm-up after a re-anchoring)."""
    frames, _ = _frames(8000, bias_from_s=30.0)
    frames = [f for f in frames if not 60.0 <= f.t_us * 1e-6 < 61.0]
    p, events, outs = _run(frames)
    assert [e.state for e in events if e.channel == CH] == [AlarmState.RAISED]
    after = [o for o, f in zip(outs, frames, strict=True) if 61.0 <= f.t_us * 1e-6 < 62.0]
    st = [s for o in after for s in o.families]
    assert all(s.judged for s in st if s.sample)
    est = [e for o in after for e in o.estimates if e.t_us == o.families[0].t_us]
    assert all(abs(e.faults[CH] - 3.0 * DEG) < 0.2 * DEG for e in est)


def test_link_bursts_are_not_stepped_across() -> None:
    """Fault-free flight with Frames lost for 0.1-0.45 s now and then (link bursts): the
    observer re-anchors instead of taking one explicit Euler step of the whole gap, so no
    false alarm, and its fault estimate stays below a tenth of the threshold (0.003 deg/s here;
    stepped across, these gaps give 0.17 deg/s, and a 0.38 s gap in a manoeuvre of a fleet
    soak gave 0.6 deg/s, a false alarm)."""
    frames, _ = _frames(9000)
    gaps = [(20.0, 0.1), (30.0, 0.2), (40.0, 0.3), (50.0, 0.38), (60.0, 0.45), (70.0, 0.25)]
    frames = [f for f in frames
              if not any(a <= f.t_us * 1e-6 < a + d for a, d in gaps)]
    _, events, outs = _run(frames)
    assert not [e for e in events if e.channel == CH]
    f_max = max(abs(e.faults[CH]) for o in outs for e in o.estimates
                if e.t_us >= 10e6 and CH in e.faults)
    assert f_max < 0.1 * CFG.fdi.threshold


def test_a_design_from_a_model_round_trips_to_the_family(tmp_path: Path) -> None:
    """What calibrate would do with an identified model: design, write, load, run."""
    import json

    from gcs_monitor.families.yaw_rate.design import design_observer, load_design

    model = load_design("transport").model
    d = design_observer(model, command="test")
    path = tmp_path / "mine.json"
    path.write_text(json.dumps(d.to_dict()))
    back = load_design(str(path))
    for s in ("r", "p"):
        np.testing.assert_allclose(back.sensors[s].L1, d.sensors[s].L1)
        assert back.sensors[s].gamma == d.sensors[s].gamma > 0.0
    # the shipped transport design is this design of the shipped model (same LMI, same data)
    np.testing.assert_allclose(back.sensors["r"].L1, load_design("transport").sensors["r"].L1,
                               rtol=1e-6, atol=1e-9)
    cfg = YawRateFamilyConfig(design=str(path))
    frames, _ = _frames(3000, bias_from_s=15.0)
    fam = YawRateFamily(cfg, FamilyContext(vehicle=1, stale_after_s=0.5))
    events = [e for o in (VehiclePipeline(1, [fam]).step(f) for f in frames) for e in o.events]
    assert [e.channel for e in events if e.state is AlarmState.RAISED] == [CH]
