"""The demo flight's alarm labels are stable (issue 15, item 7).

The first 50 s of the demo preset (aoa1 bias at 20 s, cas0 drift at 25 s, cas2 runaway at
-5 kt/s from 35 s, limited to 40 kt from 43 s) through MAVLink bytes and the default monitor,
as in tests/integration/test_golden_journal.py.

Before the label hysteresis the cas2 runaway was reported "bias" when raised, "runaway" later
and "bias" again at 48.85 s, and the aoa1 bias flipped to "oscillation" and back. Each faulty
channel must now keep one fault type from its raise to the end of the flight, the one injected.
The rule (gcs_monitor/fdi/classify.py) would let cas2 go from drift to runaway, a legitimate
change, if it were raised while its ramp still looked slow: the window must then show a ramp at
1.5 times the runaway rate (2 kt/s) in every re-classification over a window of new data (5 in
a row, 10 s), and the label changes once. It does not need to: the
classifier fits a ramp that starts inside the window (a level, then a ramp), which the 1.35 s
of -5 kt/s seen at the raise already show, so cas2 is a runaway from the raise. When the
runaway reaches its 40 kt limit, the level it leaves is explained as well by a ramp that
stopped as by a step, which is no decisive evidence for a bias: it stays a runaway.
"""

from __future__ import annotations

import dataclasses
import math

import pytest

from gcs_monitor.console import summarise_alarms
from gcs_monitor.demo import SUMMARY_HEADER, summary_rows
from gcs_monitor.fdi.events import AlarmEvent, AlarmState, FaultType
from gcs_monitor.monitor import Monitor

DURATION_S = 50.0
INJECTED = {"aoa1": FaultType.BIAS, "cas0": FaultType.DRIFT, "cas2": FaultType.RUNAWAY}


@pytest.fixture(scope="module")
def demo() -> tuple[list[AlarmEvent], list[dict[str, object]]]:
    from sim_vehicle.run import iter_packets
    from sim_vehicle.scenario import load_scenario
    from sim_vehicle.truth import fault_events

    sc = dataclasses.replace(load_scenario("demo_airdata_faults"), duration_s=DURATION_S)
    data = b"".join(p for _, p in iter_packets(sc))
    mon = Monitor()
    for i in range(0, len(data), 8192):
        mon.feed(data[i:i + 8192])
    mon.finish()
    return list(mon.events), fault_events(sc)


def test_each_faulty_channel_keeps_one_fault_type(demo):
    events, _ = demo
    raised = {str(e.channel) for e in events if e.state is AlarmState.RAISED}
    assert raised == set(INJECTED)  # and no false alarm
    for name, injected in INJECTED.items():
        own = [e for e in events if str(e.channel) == name]
        assert own[0].state is AlarmState.RAISED
        assert all(e.state is not AlarmState.CLEARED for e in own)  # latched to the end
        assert {e.fault_type for e in own} == {injected}, [(e.t_us, e.fault_type) for e in own]


def test_confidence_is_reported_in_range(demo):
    events, _ = demo
    assert all(0.0 <= e.confidence <= 1.0 for e in events)
    # the raise of a clear fault is confident
    assert all(e.confidence >= 0.5 for e in events if e.state is AlarmState.RAISED)


def test_summary_shows_first_raise_and_final_state(demo):
    events, faults = demo
    lines = summarise_alarms(events)
    assert [line.split()[:2] for line in lines] == [["v1", "aoa1"], ["v1", "cas0"],
                                                      ["v1", "cas2"]]
    for line in lines:
        first, final = line.split(" | ")
        name = first.split()[1]
        assert "first raise t=" in first and INJECTED[name].value in first
        assert final.startswith("final (t=") and "active" in final
        assert INJECTED[name].value in final
        assert "nan" not in line.lower()
    rows = summary_rows(events, faults)
    assert all(len(r) == len(SUMMARY_HEADER) for r in rows)
    assert [(r[0], r[3]) for r in rows] == [("aoa1", "detected"), ("cas0", "detected"),
                                           ("cas2", "detected")]
    for r in rows:
        assert INJECTED[r[0]].value in r[5] and INJECTED[r[0]].value in r[6]
        assert r[6].startswith("active, last event ")
        assert not any("nan" in c.lower() for c in r)
        assert math.isfinite(float(r[4]))
