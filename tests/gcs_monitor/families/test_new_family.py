"""A new family is one package and one registry line: a toy family (tests/helpers/toy_family.py)
added to the registry runs in the pipeline on real MAVLink bytes, reads its TOML section, raises
its alarm and shows in the health and the dashboard."""

from __future__ import annotations

from pathlib import Path

import pytest

from dashboards.blueprints import family_views
from gcs_monitor.config import MonitorConfig, load_config
from gcs_monitor.families import registry
from gcs_monitor.fdi.events import AlarmKind, AlarmState
from gcs_monitor.monitor import Monitor
from tests.helpers import toy_family
from tests.integration.support import base_packets, msg_name, repack


@pytest.fixture
def with_toy(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(registry, "FAMILIES", (*registry.FAMILIES, toy_family.SPEC))


def _flight(bias_mps: float, from_us: int) -> bytes:
    """The fault-free base flight with a climb-rate bias on VFR_HUD from ``from_us``."""
    out = []
    for t_us, pkt in base_packets():
        if msg_name(pkt) == "VFR_HUD" and t_us >= from_us:
            from pymavlink.dialects.v20 import ardupilotmega as mavlink

            climb = mavlink.MAVLink(None).decode(bytearray(pkt)).climb
            pkt = repack(pkt, climb=climb + bias_mps)
        out.append(pkt)
    return b"".join(out)


@pytest.mark.usefixtures("with_toy")
def test_toy_family_runs_alarms_and_reports(tmp_path: Path) -> None:
    cfg_file = tmp_path / "toy.toml"
    cfg_file.write_text("[vspeed.fdi]\nthreshold_mps = 1.5\n[imu]\nenabled = false\n"
                        "[airdata]\nenabled = false\n[yaw_rate]\nenabled = false\n"
                        "[actuators]\nenabled = false\n")
    cfg = load_config(cfg_file)
    assert cfg.family("vspeed").fdi.threshold == 1.5
    mon = Monitor(cfg)
    mon.feed(_flight(4.0, from_us=4_000_000))
    mon.finish()
    raised = [e for e in mon.events if e.state is AlarmState.RAISED
              and e.kind is AlarmKind.SENSOR_FAULT]
    assert [str(e.channel) for e in raised] == ["vspeed0"]
    assert raised[0].t_us >= 4_000_000 and raised[0].magnitude == pytest.approx(4.0, abs=0.5)
    fams = mon.health()["vehicles"]["1"]["families"]
    assert fams["vspeed"]["state"] == "judging"
    assert fams["imu"]["state"] == "disabled"
    assert [v.tab for v in family_views(cfg)] == ["Vertical speed"]


@pytest.mark.usefixtures("with_toy")
def test_toy_family_is_silent_without_a_fault() -> None:
    mon = Monitor(MonitorConfig())
    mon.feed(_flight(0.0, from_us=0))
    mon.finish()
    assert not [e for e in mon.events if str(e.channel) == "vspeed0"]
