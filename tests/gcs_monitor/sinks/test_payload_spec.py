"""docs/alarms.md is generated from the payload schema, and real payloads match it: the alarms a
monitored flight journals and publishes, its estimates, and the health its ``gcs/<vehicle>/health``
queryable answers (what ``Monitor.vehicle_health`` produces, with per-family coverage)."""

from __future__ import annotations

import json
import time
from pathlib import Path

from gcs_monitor.link.zenoh_bus import ZenohOptions, open_bus
from gcs_monitor.monitor import Monitor
from gcs_monitor.sinks.journal import AlarmJournal
from gcs_monitor.sinks.payload_spec import HEALTH, alarms_markdown, validate
from gcs_monitor.sinks.schema import health_to_dict, to_jsonable
from gcs_monitor.sinks.zenoh_sink import ZenohSink
from tests.helpers.fleet import free_port, template

ROOT = Path(__file__).resolve().parents[3]


def test_the_page_is_generated_from_the_schema() -> None:
    page = (ROOT / "docs" / "alarms.md").read_text()
    assert page == alarms_markdown(), (
        "docs/alarms.md is out of date: python -m gcs_monitor.sinks.payload_spec > "
        "docs/alarms.md")


def test_real_payloads_match_the_documented_schema(tmp_path: Path) -> None:
    ep = f"tcp/127.0.0.1:{free_port()}"
    estimates: list[dict] = []  # type: ignore[type-arg]
    with open_bus(ZenohOptions(listen=(ep,))) as bus, \
            open_bus(ZenohOptions(mode="client", connect=(ep,))) as client:
        client.subscribe("gcs/*/estimate/*", lambda k, p: estimates.append(json.loads(p)))
        journal = AlarmJournal(tmp_path / "alarms.jsonl", monitor="test")
        sinks: list[ZenohSink] = []

        def sinks_for(sysid: int) -> list:  # type: ignore[type-arg]
            sinks.append(ZenohSink(sysid, bus=bus, monitor="test"))
            return [sinks[-1], journal]

        m = Monitor(sinks_for=sinks_for, name="test")
        data = b"".join(p for _, p in template(12.0, 1, 3.0))  # AoA vane 1 bias from 3 s
        for i in range(0, len(data), 8192):
            m.feed(data[i:i + 8192])
        m.finish()
        m.publish_health()
        time.sleep(0.5)
        replies = client.get("gcs/1/health", timeout_s=3.0)
        expected = m.vehicle_health(1)
        for s in sinks:
            s.close()
        journal.close()
    lines = [json.loads(ln) for ln in (tmp_path / "alarms.jsonl").read_text().splitlines()]
    assert any(d["state"] == "raised" and d["channel_name"] == "aoa1" for d in lines)
    for d in lines:
        assert validate(d) == [], d
    assert estimates and all(validate(d) == [] for d in estimates)
    assert len(replies) == 1
    payload = json.loads(replies[0][1])
    assert validate(payload) == []
    health = payload["health"]
    # exactly what the monitor produces for the vehicle (JSON-converted); the sinks' own
    # counters move on while the payload travels
    want = json.loads(json.dumps(to_jsonable(expected)))
    assert [s["sink"] for s in health.pop("sinks")] == [s["sink"] for s in want.pop("sinks")]
    assert health == want
    assert set(health["families"]) == {"imu", "airdata", "yaw_rate", "actuators"}
    for name in ("imu", "airdata"):
        fam = health["families"][name]
        assert fam["state"] == "judging"
        assert 0.0 < fam["coverage_overall"] <= 1.0 and 0.0 <= fam["coverage_recent"] <= 1.0
    for fam in health["families"].values():  # a family that does not judge says why
        assert fam["state"] in ("judging", "degraded", "starting", "unavailable", "disabled")
        assert (fam["state"] == "judging") == (fam["reason"] == ""), fam
    assert [a["channel"] for a in health["alarms"]] == ["aoa1"]
    assert health["alarms"][0]["alarm_id"] == next(d["alarm_id"] for d in lines
                                                  if d["channel_name"] == "aoa1")


def test_an_undocumented_key_is_reported() -> None:
    h = health_to_dict({"surprise": 1}, vehicle=1, wall_time_s=0.0)
    errors = validate(h)
    assert "health.health.surprise: not documented (add it to gcs_monitor/sinks/" \
           "payload_spec.py and regenerate docs/alarms.md)" in errors
    assert "health.health.link: missing" in errors
    assert HEALTH.fields[-1].name == "health"
