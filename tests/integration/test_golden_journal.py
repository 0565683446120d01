"""Golden regression: the alarm journal of a fixed simulated flight.

The first 40 s of the demo preset (aoa1 bias at 20 s, cas0 drift at 25 s, cas2 runaway at
35 s) through MAVLink bytes and the default monitor. The committed copy
(tests/data/golden/demo_40s.events.jsonl) was first written by the code before the families
restructuring (issue 14) and regenerated for the label hysteresis (issue 15 item 7: stable
fault types, with their confidence); a change of behaviour shows in review as a diff of that
file. Exact on everything but the floats, which are compared to 1e-9 relative (their bits may
differ between BLAS builds; on one machine they are identical). Refresh deliberately with
``GCS_UPDATE_GOLDEN=1 pytest tests/integration/test_golden_journal.py``.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from pathlib import Path
from typing import Any

from gcs_monitor.fdi.events import AlarmEvent
from gcs_monitor.monitor import Monitor

GOLDEN = Path(__file__).resolve().parents[1] / "data" / "golden" / "demo_40s.events.jsonl"
DURATION_S = 40.0
FLOATS = ("magnitude", "residual_rms", "threshold", "confidence")


def _record(e: AlarmEvent) -> dict[str, Any]:
    return {"t_us": e.t_us, "channel": str(e.channel), "state": e.state.value,
            "kind": e.kind.value, "fault_type": e.fault_type.value,
            "magnitude": None if math.isnan(e.magnitude) else e.magnitude,
            "residual_rms": None if math.isnan(e.residual_rms) else e.residual_rms,
            "threshold": None if math.isnan(e.threshold) else e.threshold,
            "confidence": e.confidence,
            "estimator": e.estimator, "message": e.message, "vehicle": e.vehicle}


def journal_records() -> list[dict[str, Any]]:
    """Alarm events of the first 40 s of the demo flight, as JSON records."""
    from sim_vehicle.run import iter_packets
    from sim_vehicle.scenario import load_scenario

    sc = dataclasses.replace(load_scenario("demo_airdata_faults"), duration_s=DURATION_S)
    data = b"".join(p for _, p in iter_packets(sc))
    mon = Monitor()
    for i in range(0, len(data), 8192):
        mon.feed(data[i:i + 8192])
    mon.finish()
    return [_record(e) for e in mon.events]


def test_demo_journal_matches_the_golden_copy() -> None:
    got = journal_records()
    if os.environ.get("GCS_UPDATE_GOLDEN") == "1":
        GOLDEN.write_text("".join(json.dumps(r) + "\n" for r in got))
    want = [json.loads(line) for line in GOLDEN.read_text().splitlines()]
    assert [{k: v for k, v in r.items() if k not in FLOATS} for r in got] == \
        [{k: v for k, v in r.items() if k not in FLOATS} for r in want]
    for g, w in zip(got, want, strict=True):
        for k in FLOATS:
            assert (g[k] is None) == (w[k] is None), (g, w)
            if g[k] is not None:
                assert math.isclose(g[k], w[k], rel_tol=1e-9), (k, g, w)
    assert {r["channel"] for r in got if r["state"] == "raised"} >= {"aoa1", "cas0", "cas2"}
