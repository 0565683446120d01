"""Lu2017 experiments (gcs_monitor.evaluation.papers.lu2017): the scoring on hand-made events and
series, one preset run end to end, and the full experiment (slow)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from gcs_monitor.core.types import ChannelId
from gcs_monitor.evaluation.papers import lu2017
from gcs_monitor.families.actuators.servo import ServoTierConfig
from gcs_monitor.families.actuators.servo_filters import N_OUT
from gcs_monitor.fdi.events import AlarmEvent, AlarmKind, AlarmState, FaultType
from sim_vehicle.scenario import load_scenario


def _ev(t_s: float, surface: int, axis: str, state: AlarmState, msg: str) -> AlarmEvent:
    return AlarmEvent(t_us=round(t_s * 1e6), channel=ChannelId("surface", surface, axis),
                      state=state, kind=AlarmKind.ACTUATOR_FAULT, fault_type=FaultType.UNKNOWN,
                      magnitude=0.0, residual_rms=1.0, threshold=0.5, estimator="x",
                      message=msg)


def test_detection_scores_delay_case_and_isolation() -> None:
    events = [
        _ev(12.2, 1, "input", AlarmState.RAISED, "elevator actuator fault, class pending"),
        _ev(13.0, 1, "input", AlarmState.CLEARED, "re-classified: solid jam"),
        _ev(13.0, 1, "output", AlarmState.RAISED, "elevator solid jam: rod stuck at -44.7 mm"),
        _ev(15.0, 2, "input", AlarmState.RAISED, "rudder liquid OFC: 1 Hz"),
    ]
    d = lu2017.detection_of(events, 1, "solid_jam", 12.0)
    assert d.detected and d.delay_s == pytest.approx(0.2)
    assert (d.first_case, d.final_case) == ("unknown", "solid_jam")
    assert d.class_delay_s == pytest.approx(1.0)
    assert d.wrong_surface and not d.false_alarm_before
    free = lu2017.detection_of(events[:1], None, None, 0.0)
    assert free.false_alarm_before and not free.detected
    missed = lu2017.detection_of([], 0, "runaway", 12.0)
    assert not missed.detected and math.isnan(missed.delay_s)


def _synthetic_run(cmd_minus_pos: np.ndarray, dt: float = 0.02) -> lu2017.ServoRun:
    n = cmd_minus_pos.shape[0]
    z = np.zeros((n, 3, 3))
    rows = np.zeros((n, 3, N_OUT))
    rows[:, :, 15:17] = 1.0  # unit sigmas of the output faults
    return lu2017.ServoRun("s", np.arange(n) * dt, rows, z, z, np.zeros((n, 3)),
                           np.zeros((n, 3)), np.zeros((n, 3)), cmd_minus_pos, [], [],
                           period_s=dt)


def test_baseline_raises_on_the_rms_of_command_minus_position() -> None:
    """The fixed threshold on |command - position| over the tier's window (10 samples, 5 above
    confirm): a 0.1 rad step on the rudder from 10 s is above 0.05 from its third sample and
    confirmed at its seventh (10.12 s); a 2-sample spike whose RMS stays below is not."""
    c = np.zeros((1000, 3))
    c[500:, 2] = 0.1
    c[300:302, 0] = 0.1  # RMS over the window sqrt(2/10) x 0.1 = 0.045
    hits = lu2017.baseline_events(_synthetic_run(c), 0.05, ServoTierConfig().fdi.input)
    assert hits == [(2, pytest.approx(10.12, abs=1e-9))]


def test_calibration_of_a_quiet_run() -> None:
    run = _synthetic_run(np.full((500, 3), 0.01))
    th = lu2017.calibrate([run])
    assert th["baseline_rad"] == pytest.approx(0.015)
    assert th["input"] == 0.0 and th["output"] == 0.0


def test_one_preset_run_records_truth_and_estimates() -> None:
    """Lu2017 scenario 4 cut at 14 s through the MAVLink path: the rows and the truth line up
    (IOTSEKF rod within 0.5 mm of the true rod before the jam), the RTS-EKF's output fault
    after it is the jammed rod minus the nominal servo, and the elevator is named jammed."""
    import dataclasses

    sc = dataclasses.replace(load_scenario("lu2017_s4"), duration_s=14.0)
    run = lu2017.simulate_servo(sc)
    assert run.period_s == pytest.approx(0.02)
    pre = (run.t_s > 3.0) & (run.t_s < 12.0)
    assert np.sqrt(np.mean((run.rows[pre, 1, 2] - run.x_true[pre, 1, 0]) ** 2)) < 5e-4
    post = run.t_s > 13.0
    f_true = run.rod_true[post, 1] - run.x_nom[post, 1, 0]
    assert np.max(np.abs(run.rows[post, 1, 8] - f_true)) < 3e-3
    d = lu2017.detection_of(lu2017.tier_events(run), 1, "solid_jam", 12.0)
    assert d.detected and d.final_case == "solid_jam" and not d.wrong_surface


@pytest.mark.slow
def test_lu2017_experiment_names_every_case(tmp_path: Path) -> None:
    md = lu2017.lu2017(tmp_path, 1, True)
    assert (tmp_path / "lu2017.csv").is_file()
    assert all((tmp_path / f"lu2017_fig_s{i}.png").is_file() for i in range(6))
    rows = (tmp_path / "lu2017.csv").read_text().splitlines()[1:]
    assert "none (no alarm)" in rows[0]
    for row, label in zip(rows[1:], ("liquid OFC", "solid OFC", "liquid jam", "solid jam",
                                     "runaway"), strict=True):
        assert f"-> {label}" in row, row
    assert "S5 runaway" in md
