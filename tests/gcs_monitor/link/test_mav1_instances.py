"""MAVLink 1 framing cannot carry HIGHRES_IMU's ``id`` extension: three IMUs then read as one.
The monitor says so (health notes, a log warning, the summary) instead of merging them silently."""

from __future__ import annotations

import logging

import pytest

from gcs_monitor.link.mav import mavlink
from gcs_monitor.monitor import Monitor, mav1_note
from tests.helpers.fleet import template


def _as_mav1(packet: bytes) -> bytes:
    """The packet in strict MAVLink 1 framing: the base payload only (HIGHRES_IMU: 62 bytes,
    no ``id``), the MAVLink 1 header and CRC."""
    cls = mavlink.mavlink_map[packet[7] | packet[8] << 8 | packet[9] << 16]
    base = int(cls.instance_offset)
    payload = (packet[10:10 + packet[1]] + bytes(cls.unpacker.size))[:base]
    hdr = bytes((len(payload), packet[4], packet[5], packet[6], cls.id))
    crc = mavlink.x25crc(bytearray(hdr + payload))
    crc.accumulate(bytearray((cls.crc_extra,)))
    return b"\xfe" + hdr + payload + crc.crc.to_bytes(2, "little")


def test_three_imus_over_mavlink1_are_reported_merged(caplog: pytest.LogCaptureFixture) -> None:
    flight = template(6.0, 1, None)  # three IMUs at 100 Hz
    imu_ids = {mavlink.MAVLINK_MSG_ID_HIGHRES_IMU}
    stream = [_as_mav1(p) if (p[7] | p[8] << 8) in imu_ids else p for _, p in flight]
    n_imu = sum(1 for _, p in flight if (p[7] | p[8] << 8) in imu_ids)
    m = Monitor()
    with caplog.at_level(logging.WARNING, logger="gcs_monitor.monitor"):
        m.feed(b"".join(stream))
        m.finish()
    st = m.decoder.stats[1]
    assert st.mav1_no_instance == {"HIGHRES_IMU": n_imu}
    # 3 IMUs sampled at the same instants: 2 of every 3 time stamps repeat
    assert st.mav1_instance_repeats == pytest.approx(2 * n_imu / 3, abs=3)
    notes = m.vehicle_health(1)["notes"]
    assert notes == [mav1_note(st)]
    assert notes[0].startswith(f"MAVLink 1 framing carries no instance id ({n_imu} HIGHRES_IMU "
                               "packets): every instance reads as 0; their time stamps repeat")
    assert "several instances are merged into instance 0" in notes[0]
    assert any("merged into instance 0" in r.getMessage() for r in caplog.records)
    assert m.vehicle_health(1)["inputs"]["imu_ids"] == [0]  # what merging looks like


def test_mavlink1_frames_that_carry_the_id_give_no_note() -> None:
    """pymavlink packs extensions into MAVLink 1 frames too: then the id is there."""
    def loose_v1(packet: bytes) -> bytes:
        msg = mavlink.MAVLink(None).decode(bytearray(packet))
        mav = mavlink.MAVLink(None, srcSystem=packet[5], srcComponent=packet[6])
        mav.seq = packet[4]
        return bytes(msg.pack(mav, force_mavlink1=True))

    flight = template(3.0, 1, None)
    m = Monitor()
    m.feed(b"".join(loose_v1(p) if (p[7] | p[8] << 8) == 105 else p for _, p in flight))
    m.finish()
    assert m.vehicle_health(1)["notes"] == []
    assert m.vehicle_health(1)["inputs"]["imu_ids"] == [0, 1, 2]


def test_mavlink2_imus_give_no_note() -> None:
    m = Monitor()
    m.feed(b"".join(p for _, p in template(3.0, 1, None)))
    m.finish()
    assert m.vehicle_health(1)["notes"] == [] and m.decoder.stats[1].mav1_no_instance == {}
