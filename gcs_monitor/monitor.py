"""Monitor: link bytes -> per-vehicle Frames -> VehiclePipelines -> alarms, health.

One process serves many vehicles: decoded messages are demultiplexed by sysid; each vehicle
gets its own FrameAssembler and, once it produces Frames, its own VehiclePipeline with its own
estimators and sinks. Link problems (loss, CRC errors, stale stream, reboot, packets rejected by
MAVLink 2 signing) are LINK alarms from the link statistics, never sensor-fault alarms. Vehicle
time drives everything, so the same bytes give the same alarms.

Every alarm transition leaves the monitor through one :class:`AlarmBook` per vehicle, before any
sink sees it. The book gives each alarm its stable id (:func:`gcs_monitor.sinks.schema.alarm_id`
of vehicle, channel and raise time: the same on the raise, its updates and its clear), and keeps
the published view consistent when a vehicle's pipeline is rebuilt: after an autopilot reboot,
after a restart that found active alarms in the journal, and when a fleet worker takes a vehicle
over from another (:meth:`Monitor.adopt`). Then the alarms that were active (published) are
*inherited*:

* events at or before the **watermark** (the vehicle time up to which the previous owner had
  published) are not published again; the new pipeline, fed the buffered telemetry from before
  the watermark, warms up on them silently;
* a raise of an inherited alarm's channel is published as an ``updated`` of the inherited alarm,
  with its id: **no duplicate raise**;
* an inherited alarm that the new pipeline does not confirm within ``grace_s`` of vehicle time
  after the watermark is cleared, saying so;
* an alarm the new pipeline holds at the watermark that was not published (it raised it during
  the warm-up) is published only if it is still active ``grace_s`` later.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

from gcs_monitor.config import MonitorConfig
from gcs_monitor.core.types import ChannelId
from gcs_monitor.families import registry
from gcs_monitor.families.base import Family, FamilyContext
from gcs_monitor.fdi.alarms import AlarmStateMachine, LinkAlarmMonitor
from gcs_monitor.fdi.events import AlarmEvent, AlarmKind, AlarmState, FaultType
from gcs_monitor.fdi.records import StepOutput
from gcs_monitor.link.decode import Decoder
from gcs_monitor.pipeline import VehiclePipeline, build_families
from gcs_monitor.sinks import Sink
from gcs_monitor.sinks.schema import alarm_id, raised_t_us_of
from gcs_monitor.telemetry.assembler import FrameAssembler
from gcs_monitor.telemetry.frame import Frame

log = logging.getLogger(__name__)

GCS_SYSIDS = frozenset({255})  # ground stations: never monitored as vehicles
DEFAULT_GRACE_S = 20.0  # an inherited alarm must be confirmed within this much vehicle time
US_PER_S = 1_000_000


@dataclass
class Handover:
    """How a vehicle's monitoring started over (in health under ``handover``)."""

    reason: str  # "takeover" (another monitor's vehicle), "restart" (journal), "reboot"
    source: str = ""  # the previous owner (fleet worker id), if known
    wall_time_s: float = math.nan
    watermark_us: int | None = None  # events at or before it were the previous owner's
    inherited: int = 0  # active alarms taken over
    confirmed: int = 0  # ... re-raised by the new pipeline (published as updated)
    cleared_unconfirmed: int = 0  # ... not confirmed within the grace time: cleared
    suppressed: int = 0  # events at or before the watermark, not published again
    warmup_raised: int = 0  # raised during the warm-up, still active after the grace time
    resumed_t_us: int | None = None  # first vehicle time after the watermark

    def as_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


class AlarmBook:
    """The published alarm state of one vehicle: alarm ids and inheritance (module docstring).

    ``process(t_us, events)`` takes one Frame's events from the pipeline (and the link alarms)
    and returns the events to publish, each with its ``alarm_id``.
    """

    def __init__(self, vehicle: int, *, grace_s: float = DEFAULT_GRACE_S) -> None:
        self.vehicle = vehicle
        self.grace_us = round(grace_s * US_PER_S)
        self.public: dict[ChannelId, AlarmEvent] = {}  # active, published (last event, id set)
        self._watermark: int | None = None
        self._private: dict[ChannelId, AlarmEvent] = {}  # the pipeline's view while suppressed
        self._pending: dict[ChannelId, int] = {}  # inherited, unconfirmed: deadline (t_us)
        self._shadow: dict[ChannelId, AlarmEvent] = {}  # raised in warm-up, unpublished
        self._shadow_deadline: dict[ChannelId, int] = {}
        self._reconcile = False  # compare the views at the next Frame after the watermark
        self.handover: Handover | None = None

    def inherit(self, active: Iterable[AlarmEvent], *, watermark_us: int | None,
                reason: str, source: str = "", wall_time_s: float = math.nan,
                include_link: bool = True) -> None:
        """Start over: ``active`` are the alarms published as active (ids set); events at or
        before ``watermark_us`` are not published again (None: nothing to suppress)."""
        for ev in active:
            if ev.state is AlarmState.CLEARED:
                continue
            if not include_link and ev.kind is AlarmKind.LINK:
                continue
            aid = ev.alarm_id or alarm_id(ev.vehicle, ev.channel, ev.t_us)
            self.public[ev.channel] = dataclasses.replace(ev, alarm_id=aid)
        self._watermark = watermark_us
        self._private = {}
        self._shadow.clear()
        self._shadow_deadline.clear()
        self._pending = {}
        self._reconcile = True
        self._include_link = include_link
        self.handover = Handover(reason=reason, source=source, wall_time_s=wall_time_s,
                                 watermark_us=watermark_us,
                                 inherited=sum(1 for c, e in self.public.items()
                                               if include_link or e.kind is not AlarmKind.LINK))

    def process(self, t_us: int, events: Sequence[AlarmEvent]) -> list[AlarmEvent]:
        if self._watermark is not None and t_us <= self._watermark:
            for ev in events:  # the previous owner published these
                if ev.state is AlarmState.CLEARED:
                    self._private.pop(ev.channel, None)
                else:
                    self._private[ev.channel] = ev
            if self.handover is not None:
                self.handover.suppressed += len(events)
            return []
        out: list[AlarmEvent] = []
        if self._reconcile:
            self._start_reconcile(t_us)
        for ev in events:
            out += self._one(ev)
        if self._pending or self._shadow:
            out += self._deadlines(t_us)
        return out

    def _start_reconcile(self, t_us: int) -> None:
        self._reconcile = False
        h = self.handover
        if h is not None:
            h.resumed_t_us = t_us
        deadline = t_us + self.grace_us
        for ch, ev in self.public.items():
            if not self._include_link and ev.kind is AlarmKind.LINK:
                continue
            if ch in self._private:
                if h is not None:
                    h.confirmed += 1
            else:
                self._pending[ch] = deadline
        for ch, ev in self._private.items():
            if ch not in self.public:
                self._shadow[ch] = ev
                self._shadow_deadline[ch] = deadline
        self._private = {}
        self._watermark = None

    def _one(self, ev: AlarmEvent) -> list[AlarmEvent]:
        ch = ev.channel
        pub = self.public.get(ch)
        if ev.state is AlarmState.RAISED:
            if pub is not None:  # inherited (or double-raised): the same alarm goes on
                if ch in self._pending:
                    del self._pending[ch]
                    if self.handover is not None:
                        self.handover.confirmed += 1
                new = dataclasses.replace(ev, state=AlarmState.UPDATED, alarm_id=pub.alarm_id)
                self.public[ch] = new
                return [new]
            if ch in self._shadow:
                self._shadow[ch] = ev
                return []
            new = dataclasses.replace(ev, alarm_id=alarm_id(ev.vehicle, ch, ev.t_us))
            self.public[ch] = new
            return [new]
        if pub is not None:
            new = dataclasses.replace(ev, alarm_id=pub.alarm_id)
            if ev.state is AlarmState.CLEARED:
                del self.public[ch]
                self._pending.pop(ch, None)
            else:
                self.public[ch] = new
            return [new]
        if ch in self._shadow:  # never published: its updates and clear are not either
            if ev.state is AlarmState.CLEARED:
                del self._shadow[ch]
                del self._shadow_deadline[ch]
            else:
                self._shadow[ch] = ev
            return []
        if ev.state is AlarmState.UPDATED:  # an update of an alarm nobody published: a raise
            new = dataclasses.replace(ev, state=AlarmState.RAISED,
                                      alarm_id=alarm_id(ev.vehicle, ch, ev.t_us))
            self.public[ch] = new
            return [new]
        return []  # the clear of an alarm never published

    def _deadlines(self, t_us: int) -> list[AlarmEvent]:
        out = []
        h = self.handover
        for ch, dl in list(self._pending.items()):
            if t_us >= dl:
                del self._pending[ch]
                pub = self.public.pop(ch)
                if h is not None:
                    h.cleared_unconfirmed += 1
                why = {"takeover": "after the takeover", "restart": "after the restart",
                       "reboot": "after the autopilot reboot"}.get(
                           h.reason if h is not None else "", "after the handover")
                out.append(dataclasses.replace(
                    pub, t_us=t_us, state=AlarmState.CLEARED, magnitude=math.nan,
                    residual_rms=math.nan,
                    message=f"not confirmed within {self.grace_us / US_PER_S:g} s {why}"))
        for ch, dl in list(self._shadow_deadline.items()):
            if t_us >= dl:
                del self._shadow_deadline[ch]
                ev = self._shadow.pop(ch)
                new = dataclasses.replace(ev, t_us=t_us, state=AlarmState.RAISED,
                                          alarm_id=alarm_id(ev.vehicle, ch, t_us))
                self.public[ch] = new
                if h is not None:
                    h.warmup_raised += 1
                out.append(new)
        return out

    def active(self) -> list[AlarmEvent]:
        """The published active alarms (ids set), by channel."""
        return [self.public[ch] for ch in sorted(self.public)]


class _BookSink:
    """The one sink a VehiclePipeline sees: it passes each Frame's events through the
    vehicle's AlarmBook (ids, inheritance) and then on to the real sinks. The same
    ``StepOutput`` is returned to the monitor, so it sees the published events too."""

    def __init__(self, book: AlarmBook, sinks: list[Sink]) -> None:
        self.book = book
        self.sinks = sinks

    def publish(self, frame: Frame, out: StepOutput) -> None:
        if out.events or self.book._pending or self.book._shadow or \
                self.book._watermark is not None or self.book._reconcile:
            out.events = self.book.process(frame.t_us, out.events)
        for sink in self.sinks:
            sink.publish(frame, out)

    def update_health(self, health: dict[str, Any]) -> None:
        for sink in self.sinks:
            sink.update_health(health)

    def close(self) -> None:
        for sink in self.sinks:
            sink.close()


@dataclass
class VehicleState:
    sysid: int
    assembler: FrameAssembler
    book: AlarmBook
    pipeline: VehiclePipeline | None = None
    out: _BookSink | None = None
    link_alarms: LinkAlarmMonitor | None = None
    signing_alarm: AlarmStateMachine | None = None
    signing_seen: int = 0
    signing_last_us: int | None = None
    next_link_check_us: int = 0
    last_t_us: int = 0
    events: int = 0
    steps: list[StepOutput] = field(default_factory=list)
    mav1_warned: bool = False


class Monitor:
    """The ground-station monitor for any number of vehicles on one link.

    Parameters
    ----------
    cfg : monitor configuration
    sinks_for : builds the sinks of a newly seen vehicle (Rerun, Zenoh, journal ...)
    families_for : builds a vehicle's families from its sysid and context; default: the
        enabled families of ``cfg`` (tests give scripted ones)
    on_step : called with (sysid, frame, StepOutput) after each Frame (evaluation harness)
    raw_sink : called with every decoded message (raw input recording)
    only_sysid : monitor this system id only: messages of any other sender are counted
        (``foreign`` in health) and dropped (a fleet worker's per-vehicle stream)
    grace_s : vehicle time within which an inherited alarm must be confirmed (module
        docstring)
    inherit : alarms active before this monitor started (from the journal), per vehicle; they
        are inherited when the vehicle's pipeline starts
    name : this monitor's name in health (a fleet worker's id)
    """

    def __init__(self, cfg: MonitorConfig | None = None, *,
                 sinks_for: Callable[[int], Sequence[Sink]] = lambda sysid: (),
                 families_for: Callable[[FamilyContext], list[Family]] | None = None,
                 on_step: Callable[[int, Any, StepOutput], None] | None = None,
                 decoder: Decoder | None = None,
                 raw_sink: Callable[[Any], None] | None = None,
                 only_sysid: int | None = None, grace_s: float = DEFAULT_GRACE_S,
                 inherit: dict[int, list[AlarmEvent]] | None = None,
                 name: str = "") -> None:
        self.cfg = cfg or MonitorConfig()
        self.decoder = decoder or Decoder()
        self.only_sysid = only_sysid
        self.grace_s = grace_s
        self.name = name
        self.foreign = 0
        self._inherit = dict(inherit or {})
        self._adopt: dict[int, dict[str, Any]] = {}
        self.sinks_for = sinks_for
        self.families_for = families_for or (
            lambda ctx: build_families(dict(self.cfg.families), ctx))
        self.on_step = on_step
        self.raw_sink = raw_sink
        self.vehicles: dict[int, VehicleState] = {}
        self._link_check_us = round(self.cfg.link.check_period_s * 1e6)
        self.events: list[AlarmEvent] = []
        self.source_counters: dict[str, int] = {}

    def _vehicle(self, sysid: int) -> VehicleState:
        v = self.vehicles.get(sysid)
        if v is None:
            stats = self.decoder.vehicle_stats(sysid)
            tel = self.cfg.telemetry
            # aligned: every input of a Frame is at t_us, GPS velocity interpolated exactly
            # between the samples bracketing it; frames leave gps_delay_s behind the newest data
            v = VehicleState(sysid, FrameAssembler.aligned(tel, stats),
                             AlarmBook(sysid, grace_s=self.grace_s))
            self.vehicles[sysid] = v
        return v

    def adopt(self, sysid: int, active: Sequence[AlarmEvent], *, watermark_us: int | None,
              source: str = "", wall_time_s: float = math.nan,
              reason: str = "takeover") -> None:
        """Take vehicle ``sysid`` over with the alarms another monitor published as active;
        call before its first bytes are fed (module docstring)."""
        self._adopt[sysid] = {"active": list(active), "watermark_us": watermark_us,
                              "source": source, "wall_time_s": wall_time_s, "reason": reason}

    def _pipeline(self, v: VehicleState) -> VehiclePipeline:
        if v.pipeline is None:
            v.out = _BookSink(v.book, list(self.sinks_for(v.sysid)))
            v.pipeline = self._new_pipeline(v)
            v.link_alarms = LinkAlarmMonitor(params=self.cfg.link, vehicle=v.sysid,
                                             alarm=self.cfg.alarms)
            v.signing_alarm = AlarmStateMachine(ChannelId("link", v.sysid, "signature"),
                                                AlarmKind.LINK, "link", params=self.cfg.alarms,
                                                vehicle=v.sysid)
            adopt = self._adopt.pop(v.sysid, None)
            if adopt is not None:
                v.book.inherit(adopt["active"], watermark_us=adopt["watermark_us"],
                               reason=adopt["reason"], source=adopt["source"],
                               wall_time_s=adopt["wall_time_s"])
            elif v.sysid in self._inherit:
                v.book.inherit(self._inherit.pop(v.sysid), watermark_us=None, reason="restart")
            log.info("vehicle %d: pipeline started", v.sysid)
        return v.pipeline

    def _new_pipeline(self, v: VehicleState) -> VehiclePipeline:
        """Vehicle ``v``'s families into its book sink; its assembler computes the optional Frame
        fields only when a family reads them."""
        out, sysid = v.out, v.sysid
        assert out is not None
        # per-channel status records are built only when a sink or ``on_step`` reads them
        ctx = FamilyContext(vehicle=sysid, stale_after_s=self.cfg.telemetry.stale_after_s,
                            statuses=bool(out.sinks) or self.on_step is not None,
                            alarm=self.cfg.alarms, classifier=self.cfg.classifier)
        pipe = VehiclePipeline(sysid, self.families_for(ctx), sinks=[out],
                               coverage=self.cfg.coverage, alarm=self.cfg.alarms,
                               statuses=ctx.statuses)
        v.assembler.interp_error = pipe.reads_interp_error
        return pipe

    def feed(self, data: bytes, wall_s: float = 0.0) -> list[AlarmEvent]:
        """Decode a chunk and run every Frame it completes; return the alarm events."""
        out: list[AlarmEvent] = []
        raw = self.raw_sink
        last_sysid = -1  # messages of one vehicle come in runs: look its state up once per run
        v: VehicleState | None = None
        push: Callable[[Any], list[Any]] | None = None
        only = self.only_sysid
        for msg in self.decoder.feed(data, wall_s):
            if raw is not None:
                msg._timestamp = wall_s
                raw(msg)
            sysid = msg._header.srcSystem
            if sysid != last_sysid:
                if sysid in GCS_SYSIDS:
                    continue
                if only is not None and sysid != only:
                    self.foreign += 1
                    continue
                v = self._vehicle(sysid)
                push = v.assembler.push
                last_sysid = sysid
            frames = push(msg)  # type: ignore[misc]
            if frames:
                out += self._run(v, frames)  # type: ignore[arg-type]
        return out

    def _run(self, v: VehicleState, frames: Iterable[Any]) -> list[AlarmEvent]:
        pipe = self._pipeline(v)
        v.assembler.reboot_pending = False  # the first new-clock frame carries reset=True
        out: list[AlarmEvent] = []
        for frame in frames:
            if frame.reset:  # autopilot reboot: estimators and FDI start afresh
                # estimator states, FDI windows, latches and predictions describe the old
                # flight (whose held frames came first): new families with the same sinks
                pipe = v.pipeline = self._new_pipeline(v)
                # the new families must confirm the alarms still active (no second raise);
                # the link alarms keep their own state machines
                v.book.inherit(v.book.active(), watermark_us=None, reason="reboot",
                               include_link=False)
                # vehicle time restarted: without this no link check (and no LINK/reboot alarm)
                # would run until the new clock passed the old one
                v.next_link_check_us = 0
                v.signing_last_us = None
            extra: list[AlarmEvent] = []
            if frame.t_us >= v.next_link_check_us and v.link_alarms is not None:
                v.next_link_check_us = frame.t_us + self._link_check_us
                extra = v.link_alarms.step(frame.t_us, self._link_stats(v))
                extra += self._signing_check(v, frame.t_us)
                if not v.mav1_warned and v.assembler.stats.mav1_instance_repeats:
                    v.mav1_warned = True
                    log.warning("vehicle %d: %s", v.sysid, mav1_note(v.assembler.stats))
            step = pipe.step(frame, extra)
            v.last_t_us = frame.t_us
            if step.events:
                out += step.events
                v.events += len(step.events)
            if self.on_step is not None:
                self.on_step(v.sysid, frame, step)
        self.events += out
        return out

    def _signing_check(self, v: VehicleState, t_us: int) -> list[AlarmEvent]:
        """LINK/signature: raised while packets claiming this vehicle fail signing (unsigned,
        wrong key, replayed), cleared ``crc_hold_s`` after the last one."""
        st = v.assembler.stats
        n = st.signature_failures
        if n > v.signing_seen:
            v.signing_seen = n
            v.signing_last_us = t_us
        on = v.signing_last_us is not None and (
            t_us - v.signing_last_us < self.cfg.link.crc_hold_s * US_PER_S)
        assert v.signing_alarm is not None
        return v.signing_alarm.step(
            t_us, on, fault_type=FaultType.LINK, magnitude=float(n),
            message=(f"{n} packets rejected by signing (unsigned {st.unsigned_rejected}, "
                     f"wrong key {st.wrong_key}, replayed {st.replayed})"))

    def _link_stats(self, v: VehicleState) -> dict[str, float]:
        st = v.assembler.stats
        return {"lost": float(st.lost), "messages": float(st.messages),
                "crc_errors": float(self.decoder.counters.parse_errors),
                "boot_count": float(st.reboots), "duplicate_sysid": float(st.duplicate_sysid)}

    def finish(self) -> list[AlarmEvent]:
        """End of input: decode bytes still held, then flush held frames through the pipelines."""
        out: list[AlarmEvent] = []
        for msg in self.decoder.flush():
            sysid = msg._header.srcSystem
            if sysid not in GCS_SYSIDS:
                frames = self._vehicle(sysid).assembler.push(msg)
                if frames:
                    out += self._run(self._vehicle(sysid), frames)
        for v in self.vehicles.values():
            frames = v.assembler.flush()
            if frames:
                out += self._run(v, frames)
        return out

    def vehicle_health(self, sysid: int) -> dict[str, Any]:
        """One vehicle's health: what ``gcs/<vehicle>/health`` answers (docs/alarms.md)."""
        v = self.vehicles[sysid]
        avail = v.assembler.availability()
        st = v.assembler.stats
        return {
            "monitor": self.name,
            "vehicle_time_s": v.last_t_us * 1e-6,
            "link": st.as_dict(),
            "link_wide": self.decoder.counters.as_dict() | self.source_counters
            | {"foreign": self.foreign},
            "notes": [mav1_note(st)] if st.mav1_no_instance else [],
            "inputs": avail,
            "families": family_availability(avail, self.cfg.families, v.pipeline),
            "alarms": [alarm_summary(ev) for ev in v.book.active()],
            "handover": v.book.handover.as_dict() if v.book.handover is not None else None,
            "sinks": [sink_health(s) for s in v.out.sinks] if v.out is not None else [],
        }

    def health(self) -> dict[str, Any]:
        return {"link": self.decoder.counters.as_dict() | self.source_counters
                | {"foreign": self.foreign},
                "vehicles": {str(sysid): self.vehicle_health(sysid)
                             for sysid in self.vehicles}}

    def publish_health(self, extra: dict[str, Any] | None = None) -> None:
        """Hand every vehicle's health to its sinks (``extra`` keys added, e.g. ``fleet``)."""
        for sysid, v in self.vehicles.items():
            if v.out is not None and v.out.sinks:
                h = self.vehicle_health(sysid)
                if extra:
                    h.update(extra)
                for sink in v.out.sinks:
                    sink.update_health(h)

    def close(self) -> None:
        self.publish_health()
        for v in self.vehicles.values():
            if v.pipeline is not None:
                v.pipeline.close()


def alarm_summary(ev: AlarmEvent) -> dict[str, Any]:
    """An active alarm in health: id, channel, kind, type, confidence, magnitude, raise."""
    return {"alarm_id": ev.alarm_id, "channel": str(ev.channel), "kind": ev.kind.value,
            "fault_type": ev.fault_type.value, "confidence": ev.confidence,
            "magnitude": ev.magnitude, "since_t_us": raised_t_us_of(ev.alarm_id),
            "last_t_us": ev.t_us}


def mav1_note(st: Any) -> str:
    """The warning for instance ids that MAVLink 1 framing cannot carry (HIGHRES_IMU id)."""
    kinds = ", ".join(f"{n} {k}" for k, n in sorted(st.mav1_no_instance.items()))
    merged = (f"; their time stamps repeat or step back {st.mav1_instance_repeats} times: "
              f"several instances are merged into instance 0"
              if st.mav1_instance_repeats else "")
    return (f"MAVLink 1 framing carries no instance id ({kinds} packets): every instance reads "
            f"as 0{merged}; switch the link to MAVLink 2")


def sink_health(sink: Any) -> dict[str, Any]:
    """A sink's own counters (a Zenoh session that failed, payloads dropped) for health."""
    out: dict[str, Any] = {"sink": type(sink).__name__}
    for k in ("active", "n_published", "n_dropped", "n_errors"):
        v = getattr(sink, k, None)
        if isinstance(v, bool | int | float):
            out[k] = v
    return out


def family_availability(avail: dict[str, Any], configs: Any,
                        pipeline: VehiclePipeline | None) -> dict[str, dict[str, Any]]:
    """Per registered family: ``state`` (judging, degraded, starting, unavailable, disabled),
    its coverage (the share of the last window and of the flight it judged) and the reason it
    did not judge; "available" means judging."""
    out: dict[str, dict[str, Any]] = {}
    for spec in registry.FAMILIES:
        cfg = configs.get(spec.name)
        row: dict[str, Any] = {"title": spec.title, "coverage_recent": math.nan,
                               "coverage_overall": math.nan}
        if cfg is None or not cfg.enabled:
            out[spec.name] = row | {"state": "disabled", "reason": ""}
            continue
        cov = pipeline.coverage.get(spec.name) if pipeline is not None else None
        missing = spec.missing_inputs(avail)
        if cov is None or cov.state == "unavailable":
            why = ("missing " + ", ".join(missing)) if missing else (
                cov.coverage.reason if cov is not None else "no frame yet")
            out[spec.name] = row | {"state": "unavailable", "reason": why}
            continue
        c = cov.coverage
        out[spec.name] = row | {"state": c.state, "reason": c.reason,
                                "coverage_recent": c.recent, "coverage_overall": c.overall}
    return out
