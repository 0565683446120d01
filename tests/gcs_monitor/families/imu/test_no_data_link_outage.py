"""A link outage silences every IMU at once: no IMU no-data alarm when the link comes back
(found by the fleet soak: the first frame after an outage came before the other instances'
samples of that instant, so two IMUs looked silent for the outage's length)."""

from __future__ import annotations

from gcs_monitor.fdi.events import AlarmKind
from gcs_monitor.monitor import Monitor
from tests.helpers.fleet import template

S = 1_000_000


def test_a_link_outage_raises_no_imu_no_data_alarm() -> None:
    flight = template(14.0, 1, None)  # three IMUs
    # 2.5 s with nothing; the link comes back in the middle of a time step, with its last IMU
    start = next(k for k, (t, _) in enumerate(flight) if t >= 6 * S)
    end = next(k for k, (t, p) in enumerate(flight) if t >= int(8.5 * S) and _is_imu(p, 2))
    m = _run([p for k, (_, p) in enumerate(flight) if not start <= k < end])
    assert not [e for e in m.events if e.kind is AlarmKind.SENSOR_FAULT]
    assert any(e.channel.axis == "loss" for e in m.events)  # the link alarm says what it was


def test_one_silent_imu_is_still_reported() -> None:
    flight = template(10.0, 1, None)
    imu1 = [p for t, p in flight if (p[7] | p[8] << 8) == 105 and p[-2:] and t >= 4 * S]
    drop = {id(p) for p in imu1}
    kept = [p for _, p in flight if id(p) not in drop or not _is_imu(p, 1)]
    m = _run(kept)
    raised = [str(e.channel) for e in m.events if e.kind is AlarmKind.SENSOR_FAULT]
    assert raised == ["imu1"]


def _run(packets: list[bytes]) -> Monitor:
    m = Monitor()
    data = b"".join(packets)
    for i in range(0, len(data), 2048):  # as a live link delivers it
        m.feed(data[i:i + 2048])
    m.finish()
    return m


def _is_imu(p: bytes, inst: int) -> bool:
    from gcs_monitor.link.mav import mavlink

    return (p[7] | p[8] << 8) == 105 and mavlink.MAVLink(None).decode(bytearray(p)).id == inst
