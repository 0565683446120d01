"""Crafted telemetry through the whole Monitor (issue 15, item 6): one bad clock value, the
clock stepping back and forward, and link alarms that clear when their condition ends.

Each test asserts the complete list of alarm events, "exactly the expected alarms, nothing
else". The base is a fault-free simulated flight (tests/integration/support.py); time stamps
are shifted by re-encoding the packets with the same sender and sequence number.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from gcs_monitor.fdi.events import AlarmEvent
from gcs_monitor.link.mav import mavlink
from tests.helpers.mavgen import Packet, drop, join
from tests.integration.support import clean_packets, msg_name, repack, run_monitor

FLIGHT_S = 20.0  # long enough for every alarm below to clear on the new time line
STEP_AT_US = 4_000_000


def _events(events: list[AlarmEvent]) -> list[tuple[str, str, str]]:
    return [(e.state.value, str(e.channel), e.kind.value) for e in events]


def _shift(packet: bytes, d_us: int) -> bytes:
    """The packet with every vehicle time stamp it carries moved by ``d_us``."""
    m = mavlink.MAVLink(None).decode(bytearray(packet))
    fields = {}
    if hasattr(m, "time_usec"):
        fields["time_usec"] = m.time_usec + d_us
    if hasattr(m, "time_boot_ms"):
        fields["time_boot_ms"] = m.time_boot_ms + d_us // 1000
    return repack(packet, **fields) if fields else packet


def _clock_step(packets: list[Packet], d_us: int) -> list[Packet]:
    """The vehicle clock of every stream steps by ``d_us`` at ``STEP_AT_US``."""
    return [(t, _shift(p, d_us) if t >= STEP_AT_US else p) for t, p in packets]


@pytest.fixture(scope="module")
def flight() -> list[Packet]:
    return clean_packets(FLIGHT_S)


def test_a_single_2_63_time_stamp(base_packets):
    """One HIGHRES_IMU of the primary IMU says ``time_usec = 2^63``: rejected and counted, no
    alarm at all (it used to raise a LINK/reboot at t_us = 2^63 that never cleared)."""
    out, done = [], False
    for t, p in base_packets:
        if not done and t >= STEP_AT_US and msg_name(p) == "HIGHRES_IMU" and \
                mavlink.MAVLink(None).decode(bytearray(p)).id == 0:
            p, done = repack(p, time_usec=1 << 63), True
        out.append((t, p))
    r = run_monitor(join(out))
    assert r.events == []
    lk = r.health["vehicles"]["1"]["link"]
    assert lk["time_rejected"] == 1 and lk["bad_values"] == {"HIGHRES_IMU.time_usec": 1}
    assert lk["reboots"] == 0 and lk["time_jumps"] == 0
    assert lk["last_vehicle_t_us"] <= base_packets[-1][0]
    assert r.builds == [["imu", "airdata", "yaw_rate", "actuators"]]


def test_the_clock_stepping_back(flight):
    """An autopilot reboot: every stream's clock restarts at 0.1 s. A LINK/reboot alarm,
    raised at the first frame of the new clock and cleared ``reboot_hold_s`` (5 s) later on it;
    the families start afresh once; nothing else."""
    r = run_monitor(join(_clock_step(flight, 100_000 - STEP_AT_US)))
    assert _events(r.events) == [("raised", "link1.reboot", "link"),
                                 ("cleared", "link1.reboot", "link")]
    assert [e.t_us for e in r.events] == [100_000, 5_100_000]
    lk = r.health["vehicles"]["1"]["link"]
    assert lk["reboots"] == 1 and lk["time_rejected"] == 0 and lk["time_jumps"] == 0
    families = ["imu", "airdata", "yaw_rate", "actuators"]
    assert r.builds == [families, families]


def test_the_clock_stepping_forward(flight):
    """Every stream's clock jumps 60 s ahead (a telemetry outage, or a clock step): the
    following samples confirm the later time line, so it is the vehicle's (``time_jumps``), not
    an outlier, and not a reboot (the flight and the FDI's knowledge go on). Vehicle time
    without data is time not judged: the IMU family, whose estimator re-anchors over the gap,
    reports ``monitor_degraded`` from the first frame after the step until it has judged 90 %
    of a 10 s window again; so does the yaw-rate family, which cannot judge the first frames
    after the step (the untimed AIRSPEED of the new time line arrives after them) and whose
    observer re-anchors at the first sample with all its inputs; so does the actuator family
    (60 s without commands are 60 s not judged); the air-data sets judge from the first sample.
    Nothing else."""
    jump_us = 60_000_000
    r = run_monitor(join(_clock_step(flight, jump_us)))
    assert sorted(_events(r.events)) == sorted(
        [("raised", "monitor0.imu", "monitor_degraded"),
         ("cleared", "monitor0.imu", "monitor_degraded"),
         ("raised", "monitor0.yaw_rate", "monitor_degraded"),
         ("cleared", "monitor0.yaw_rate", "monitor_degraded"),
         ("raised", "monitor0.actuators", "monitor_degraded"),
         ("cleared", "monitor0.actuators", "monitor_degraded")])
    for fam in ("imu", "yaw_rate", "actuators"):
        raised, cleared = (e.t_us for e in r.events if e.channel.axis == fam)
        assert raised == STEP_AT_US + jump_us
        assert 9_000_000 <= cleared - raised <= 12_000_000
    lk = r.health["vehicles"]["1"]["link"]
    assert lk["time_jumps"] == 1 and lk["time_rejected"] == 0 and lk["reboots"] == 0
    assert r.builds == [["imu", "airdata", "yaw_rate", "actuators"]]


def test_a_lone_forward_outlier(base_packets):
    """One primary IMU sample 0.3 s ahead (beyond REBOOT_CONFIRM periods, so that accepted it
    would fake a reboot): rejected and counted, no alarm."""
    out, done = [], False
    for t, p in base_packets:
        if not done and t >= STEP_AT_US and msg_name(p) == "HIGHRES_IMU":
            p, done = _shift(p, 300_000), True
        out.append((t, p))
    r = run_monitor(join(out))
    assert r.events == []
    lk = r.health["vehicles"]["1"]["link"]
    assert lk["time_rejected"] == 1 and lk["reboots"] == 0 and lk["time_backwards"] == 0


def test_packet_loss_alarm_clears_when_the_link_recovers(flight):
    """30 % loss for 4 s, then a clean link: LINK/loss is measured over the last 10 s, so it
    clears 10 s after the loss stopped (the cumulative loss of the flight stays above 2 %)."""
    head = [tp for tp in flight if tp[0] < STEP_AT_US]
    tail = [tp for tp in flight if tp[0] >= STEP_AT_US]
    r = run_monitor(join(drop(head, 0.3, np.random.default_rng(5)) + tail))
    loss = [e for e in r.events if e.channel.axis == "loss"]
    assert all(e.kind.value == "link" for e in r.events) and loss == r.events
    assert loss[0].state.value == "raised" and loss[-1].state.value == "cleared"
    assert [e.state.value for e in loss[1:-1]] == ["updated"] * (len(loss) - 2)
    assert 10_000_000 <= loss[-1].t_us - STEP_AT_US <= 11_500_000
    assert r.health["vehicles"]["1"]["link"]["loss_pct"] > 2.0


def test_duplicate_sysid_alarm_clears_when_the_second_sender_stops(flight):
    """A second simulated vehicle uses the same system id for the first 4 s: LINK/
    duplicate_sysid is raised while both are heard and cleared after it went quiet."""
    from sim_vehicle.run import iter_packets
    from sim_vehicle.scenario import load_scenario

    sc = dataclasses.replace(load_scenario("lu2016_calm"), faults=(), duration_s=4.0, seed=7)
    merged = sorted(flight + list(iter_packets(sc)), key=lambda tp: tp[0])
    r = run_monitor(join(merged))
    assert _events(r.events) == [("raised", "link1.duplicate_sysid", "link"),
                                 ("cleared", "link1.duplicate_sysid", "link")]
    assert STEP_AT_US < r.events[1].t_us <= STEP_AT_US + 2_000_000
    lk = r.health["vehicles"]["1"]["link"]
    assert lk["duplicate_sysid_seen"] and not lk["duplicate_sysid"]
