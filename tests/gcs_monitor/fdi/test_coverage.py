"""Coverage of a family on hand-written status sequences: start-up not counted, the share of
time judged, monitor_degraded raised below 90 % and cleared above 95 % (hysteresis), never for
a family whose inputs never appeared."""

from __future__ import annotations

import pytest

from gcs_monitor.fdi.coverage import CoverageConfig, FamilyCoverage
from gcs_monitor.fdi.events import AlarmKind, AlarmState
from gcs_monitor.fdi.records import FamilyStatus

DT = 10_000  # 100 Hz Frames


def _feed(cov: FamilyCoverage, t0: int, t1: int, judged: bool, reason: str = "",
          inputs: bool = True) -> list:
    events = []
    for t in range(t0, t1, DT):
        events += cov.step(FamilyStatus("imu", t, judged, reason="" if judged else reason,
                                        inputs=inputs))
    return events


def test_never_inputs_is_unavailable_and_silent() -> None:
    cov = FamilyCoverage("airdata", CoverageConfig())
    assert _feed(cov, 0, 60_000_000, False, "no air data", inputs=False) == []
    assert cov.coverage.state == "unavailable" and cov.coverage.reason == "no air data"


def test_startup_then_judging() -> None:
    cov = FamilyCoverage("imu", CoverageConfig())
    assert _feed(cov, 0, 5_000_000, False, "imu_ts: warm-up") == []  # 5 s warm-up
    assert cov.coverage.state == "starting"
    assert _feed(cov, 5_000_000, 30_000_000, True) == []
    c = cov.coverage
    assert c.state == "judging" and c.recent == 1.0 and c.overall == 1.0


def test_degraded_below_90_cleared_above_95() -> None:
    cfg = CoverageConfig()
    cov = FamilyCoverage("imu", cfg)
    _feed(cov, 0, 20_000_000, True)
    # blind for 2 s: the share of the 10 s window falls below 0.9 after 1 s + hold 0.5 s
    ev = _feed(cov, 20_000_000, 22_000_000, False, "imu_ts: warm-up")
    assert [(e.state, e.kind) for e in ev] == [(AlarmState.RAISED, AlarmKind.MONITOR_DEGRADED)]
    raised = ev[0]
    # uncovered from 20.5 s (hold) to 21.5 s: 1 s of 10 s, the first instant it exceeds 10 %
    assert raised.t_us == pytest.approx(21_510_000, abs=DT)
    assert "imu_ts: warm-up" in raised.message and str(raised.channel) == "monitor0.imu"
    ev = _feed(cov, 22_000_000, 40_000_000, True)
    assert [e.state for e in ev] == [AlarmState.CLEARED]
    # cleared when the uncovered 1.5 s (20.5-22 s) is less than 5 % of the window: it has left
    # the window enough, i.e. 10 s after the start of the gap minus 0.5 s
    assert ev[0].t_us == pytest.approx(30_510_000 + 1_000_000, abs=1_000_000)
    assert cov.coverage.state == "judging"
    assert 0.9 < cov.coverage.overall < 1.0


def test_hold_covers_a_slower_stream() -> None:
    # a 20 Hz stream on 100 Hz Frames: judged on every fifth Frame, covered throughout
    cov = FamilyCoverage("airdata", CoverageConfig())
    events = []
    for k in range(3000):
        events += cov.step(FamilyStatus("airdata", k * DT, k % 5 == 0, sample=k % 5 == 0,
                                        reason="" if k % 5 == 0 else "no new air data"))
    assert events == [] and cov.coverage.recent == 1.0


def test_frames_between_samples_count_under_the_last_samples_reason() -> None:
    """A 25 Hz observer on 100 Hz Frames, out of its speed range for 5 s: three Frames in four
    say "between observer steps" (no sample of its own), the others why the sample was not
    judged; the alarm names the latter (the reason with the most uncovered time named the
    former in the Wan2018 campaign)."""
    cov = FamilyCoverage("yaw_rate", CoverageConfig())
    events = []
    for k in range(4000):
        t = k * DT
        own = k % 4 == 0
        judged = own and not 2000 <= k < 2500
        why = "" if judged else ("EAS below the design's range" if own else
                                 "between observer steps")
        events += cov.step(FamilyStatus("yaw_rate", t, judged, sample=own, reason=why))
    raised = [e for e in events if e.state is AlarmState.RAISED]
    assert len(raised) == 1 and raised[0].message.endswith("EAS below the design's range")
    # a stream that stops: after hold_s its Frames' own reason counts again
    cov = FamilyCoverage("airdata", CoverageConfig())
    for k in range(3000):
        own = k % 5 == 0 and k < 2000
        cov.step(FamilyStatus("airdata", k * DT, own, sample=own,
                              reason="" if own else "no new air data"))
    assert cov.coverage.reason == "no new air data"


def test_bad_config() -> None:
    with pytest.raises(ValueError, match="min_coverage"):
        CoverageConfig(min_coverage=0.96, clear_coverage=0.95)
