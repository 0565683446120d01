"""The assembler's vehicle-clock rules (issue 15 item 6; module docstring of
gcs_monitor/telemetry/assembler.py, "Vehicle clock"): one focused test per rule.

Streams come from tests/helpers/mavgen.py (3 IMUs and attitude at 100 Hz, GPS 10 Hz, air data
20 Hz); a damaged packet is re-encoded with the same sender and sequence number.
"""

from __future__ import annotations

import pytest

from gcs_monitor.link.decode import Decoder
from gcs_monitor.link.mav import mavlink
from gcs_monitor.telemetry.assembler import MAX_VEHICLE_T_US, REBOOT_CONFIRM, FrameAssembler
from gcs_monitor.telemetry.frame import Frame
from tests.helpers.mavgen import MavGen, Packet, join
from tests.integration.support import msg_name, repack

T0_US = 5_000_000
PERIOD_US = 10_000  # MavGen's IMU period


def _run(packets: list[Packet]) -> tuple[FrameAssembler, list[Frame]]:
    d = Decoder()
    a = FrameAssembler(stats=d.vehicle_stats(1))  # mode "latest": one frame per primary sample
    frames = a.push_many(d.feed(join(packets), 0.0))
    return a, frames


def _instance(packet: bytes) -> int:
    return int(mavlink.MAVLink(None).decode(bytearray(packet)).id)


def _damage_one(packets: list[Packet], name: str, at_us: int, **fields: int) -> list[Packet]:
    """``packets`` with the first ``name`` packet (instance 0 for HIGHRES_IMU) at or after
    ``at_us`` re-encoded with ``fields``."""
    out, done = [], False
    for t, p in packets:
        if not done and t >= at_us and msg_name(p) == name and (
                name != "HIGHRES_IMU" or _instance(p) == 0):
            p, done = repack(p, **fields), True
        out.append((t, p))
    assert done
    return out


@pytest.fixture(scope="module")
def clean() -> list[Packet]:
    return MavGen().packets(2.0)


def test_clean_stream_has_no_clock_rejection(clean):
    a, frames = _run(clean)
    st = a.stats
    assert (st.time_rejected, st.time_jumps, st.reboots) == (0, 0, 0)
    assert len(frames) == 200
    assert a.jump_bound_us() == REBOOT_CONFIRM * PERIOD_US


@pytest.mark.parametrize("t_us", [1 << 63, (1 << 64) - 1, MAX_VEHICLE_T_US + 1])
def test_a_time_stamp_no_clock_can_carry_is_rejected(clean, t_us):
    """2^63 does not fit an int64 and is 292 000 years of uptime; beyond 2100-01-01 as UNIX
    time no MAVLink clock (boot or UNIX time) can be."""
    a, frames = _run(_damage_one(clean, "HIGHRES_IMU", T0_US + 1_000_000, time_usec=t_us))
    st = a.stats
    assert st.time_rejected == 1 and st.bad_values == {"HIGHRES_IMU.time_usec": 1}
    assert st.reboots == 0 and st.time_backwards == 0
    assert len(frames) == 199  # that one primary sample is missing, nothing else
    assert max(f.t_us for f in frames) < T0_US + 2_000_000


@pytest.mark.parametrize("ahead_us", [6 * PERIOD_US, 300_000, 1_000_000_000])
def test_a_lone_imu_sample_ahead_of_the_time_line_is_rejected(clean, ahead_us):
    """More than REBOOT_CONFIRM periods ahead, followed by samples on the old line: an outlier.
    Accepted, it would have left 5 or more samples behind it: a fake reboot."""
    at = T0_US + 1_000_000
    a, frames = _run(_damage_one(clean, "HIGHRES_IMU", at, time_usec=at + ahead_us))
    st = a.stats
    assert st.time_rejected == 1 and st.reboots == 0 and st.time_backwards == 0
    assert [f.t_us for f in frames] == [T0_US + PERIOD_US * k for k in range(200) if k != 100]


def test_a_sample_just_ahead_is_a_reordering_not_a_reboot(clean):
    """Within the bound, the samples left behind are fewer than REBOOT_CONFIRM: the existing
    reorder logic drops them (time_backwards), no reboot."""
    at = T0_US + 1_000_000
    a, _ = _run(_damage_one(clean, "HIGHRES_IMU", at, time_usec=at + 4 * PERIOD_US))
    st = a.stats
    assert st.time_rejected == 0 and st.reboots == 0 and st.time_backwards >= 1


def test_a_forward_step_confirmed_by_the_following_samples_is_the_new_time_line():
    g = MavGen()
    before = g.packets(1.0)
    after = g.packets(1.0, start_us=T0_US + 61_000_000)  # 60 s later (an outage, a clock step)
    a, frames = _run(before + after)
    st = a.stats
    assert st.time_jumps == 1 and st.time_rejected == 0 and st.reboots == 0
    assert len(frames) == 200  # the held samples were replayed: none lost
    assert frames[100].t_us == T0_US + 61_000_000 and not frames[100].reset


def test_a_secondary_stream_far_ahead_of_the_imu_is_rejected(clean):
    at = T0_US + 1_000_000
    damaged = _damage_one(clean, "GLOBAL_POSITION_INT", at, time_boot_ms=at // 1000 + 100_000)
    a, frames = _run(damaged)
    st = a.stats
    assert st.time_rejected == 1 and st.bad_values == {"GLOBAL_POSITION_INT.time_boot_ms": 1}
    # the GPS history was not wiped by a sample "from the future": velocity on every frame
    assert all(f.gps_vel_ned_mps is not None for f in frames if f.t_us > T0_US + 300_000)


def test_an_imu_silent_while_the_other_streams_go_on_is_no_clock_fault():
    """No HIGHRES_IMU for 3 s while attitude, GPS and air data go on: nothing is rejected, and
    the IMU is taken at once when it resumes (the other streams kept the time line)."""
    g = MavGen()
    pk = g.packets(6.0)
    gap = (T0_US + 2_000_000, T0_US + 5_000_000)
    kept = [(t, p) for t, p in pk if not (gap[0] <= t < gap[1] and msg_name(p) == "HIGHRES_IMU")]
    a, frames = _run(kept)
    st = a.stats
    assert (st.time_rejected, st.time_jumps, st.reboots) == (0, 0, 0)
    assert len(frames) == 300 and frames[200].t_us == gap[1]


def test_a_forward_step_is_confirmed_by_the_other_streams():
    """After the step the first IMU samples are held; attitude and GPS on the same later line
    confirm it with the IMU samples that follow."""
    g = MavGen(n_imu=1)
    before = g.packets(1.0)
    after = g.packets(1.0, start_us=T0_US + 61_000_000)
    a, frames = _run(before + after)
    assert a.stats.time_jumps == 1 and a.stats.time_rejected == 0
    assert len(frames) == 200
