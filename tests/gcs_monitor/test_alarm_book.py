"""AlarmBook: stable alarm ids, and inheritance without duplicate raises (takeover, restart,
autopilot reboot), on hand-written event sequences."""

from __future__ import annotations

import math

from gcs_monitor.core.types import ChannelId
from gcs_monitor.fdi.events import AlarmEvent, AlarmKind, AlarmState, FaultType
from gcs_monitor.monitor import AlarmBook
from gcs_monitor.sinks.schema import alarm_id, raised_t_us_of

AOA1, CAS0, LOSS = ChannelId("aoa", 1), ChannelId("cas", 0), ChannelId("link", 1, "loss")
S = 1_000_000


def ev(t_s: float, ch: ChannelId, state: AlarmState, kind: AlarmKind = AlarmKind.SENSOR_FAULT,
       mag: float = 0.05) -> AlarmEvent:
    return AlarmEvent(round(t_s * S), ch, state, kind, FaultType.BIAS, mag, 0.04, 0.02,
                      "voting", "", vehicle=1, confidence=0.9)


R, U, C = AlarmState.RAISED, AlarmState.UPDATED, AlarmState.CLEARED


def test_ids_are_vehicle_channel_raise_time_on_every_transition() -> None:
    book = AlarmBook(1)
    out = book.process(10 * S, [ev(10.0, AOA1, R)])
    out += book.process(11 * S, [ev(11.0, AOA1, U)])
    out += book.process(12 * S, [ev(12.0, AOA1, C)])
    assert [e.state for e in out] == [R, U, C]
    assert {e.alarm_id for e in out} == {"1/aoa1/10000000"} == {alarm_id(1, AOA1, 10 * S)}
    assert raised_t_us_of(out[0].alarm_id) == 10 * S
    again = book.process(20 * S, [ev(20.0, AOA1, R)])  # a new raise is a new alarm
    assert again[0].alarm_id == "1/aoa1/20000000"
    assert out[0] == ev(10.0, AOA1, R)  # the id is not part of equality


def test_takeover_suppresses_up_to_the_watermark_and_confirms_without_a_second_raise() -> None:
    inherited = AlarmBook(1).process(10 * S, [ev(10.0, AOA1, R)])
    book = AlarmBook(1, grace_s=5.0)
    book.inherit(inherited, watermark_us=30 * S, reason="takeover", source="wA")
    # the new pipeline, fed buffered frames, raises aoa1 at 10.3 s: the previous owner's
    assert book.process(int(10.3 * S), [ev(10.3, AOA1, R)]) == []
    assert book.process(30 * S, []) == []
    # first frame after the watermark: aoa1 is held by both: nothing to publish
    assert book.process(int(30.01 * S), []) == []
    out = book.process(31 * S, [ev(31.0, AOA1, U, mag=0.06)])
    assert [(e.state, e.alarm_id) for e in out] == [(U, "1/aoa1/10000000")]
    h = book.handover
    assert h is not None and (h.inherited, h.confirmed, h.cleared_unconfirmed) == (1, 1, 0)
    assert h.suppressed == 1 and h.resumed_t_us == int(30.01 * S) and h.source == "wA"


def test_a_re_raise_after_the_watermark_is_an_update_of_the_inherited_alarm() -> None:
    inherited = AlarmBook(1).process(10 * S, [ev(10.0, AOA1, R)])
    book = AlarmBook(1, grace_s=5.0)
    book.inherit(inherited, watermark_us=30 * S, reason="takeover")
    book.process(int(30.5 * S), [])  # cold start: the new pipeline has not raised it yet
    out = book.process(32 * S, [ev(32.0, AOA1, R)])
    assert [(e.state, e.alarm_id) for e in out] == [(U, "1/aoa1/10000000")]
    assert book.handover is not None and book.handover.confirmed == 1


def test_an_unconfirmed_inherited_alarm_is_cleared_after_the_grace_time() -> None:
    inherited = AlarmBook(1).process(10 * S, [ev(10.0, AOA1, R)])
    book = AlarmBook(1, grace_s=5.0)
    book.inherit(inherited, watermark_us=30 * S, reason="takeover")
    assert book.process(31 * S, []) == []
    assert book.process(int(35.9 * S), []) == []
    out = book.process(36 * S, [])
    assert [(e.state, e.alarm_id, e.t_us) for e in out] == [(C, "1/aoa1/10000000", 36 * S)]
    assert "not confirmed within 5 s after the takeover" in out[0].message
    assert math.isnan(out[0].magnitude) and book.active() == []
    assert book.handover is not None and book.handover.cleared_unconfirmed == 1


def test_a_warm_up_raise_is_published_only_if_it_lasts_the_grace_time() -> None:
    book = AlarmBook(1, grace_s=5.0)
    book.inherit([], watermark_us=30 * S, reason="takeover")
    book.process(29 * S, [ev(29.0, CAS0, R)])  # raised in the warm-up, unknown to the owner
    book.process(29 * S, [ev(29.0, AOA1, R)])
    assert book.process(int(30.1 * S), []) == []
    assert book.process(31 * S, [ev(31.0, AOA1, C)]) == []  # cleared in time: never published
    out = book.process(int(35.1 * S), [])
    assert [(e.channel, e.state, e.alarm_id) for e in out] == [(CAS0, R, "1/cas0/35100000")]
    assert book.handover is not None and book.handover.warmup_raised == 1


def test_reboot_keeps_link_alarms_and_asks_the_families_to_confirm_theirs() -> None:
    book = AlarmBook(1, grace_s=5.0)
    book.process(10 * S, [ev(10.0, AOA1, R), ev(10.0, LOSS, R, AlarmKind.LINK)])
    book.inherit(book.active(), watermark_us=None, reason="reboot", include_link=False)
    out = book.process(1 * S, [ev(1.0, AOA1, R)])  # new clock: the families raise it again
    assert [(e.state, e.alarm_id) for e in out] == [(U, "1/aoa1/10000000")]
    out = book.process(2 * S, [ev(2.0, LOSS, C, AlarmKind.LINK)])  # the link monitor's own
    assert [(e.state, e.alarm_id) for e in out] == [(C, "1/link1.loss/10000000")]
    assert book.process(20 * S, []) == []  # nothing pending any more
