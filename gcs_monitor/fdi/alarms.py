"""Alarm state machines: decisions in, :class:`AlarmEvent` transitions out.

One :class:`AlarmStateMachine` per channel.  ``step`` takes the confirmed decision and the
current fault description and returns the transition events of this sample (usually an
empty list): RAISED on entry, UPDATED when the fault type changes or the magnitude moves
by more than ``update_rel_change`` (rate-limited to one per ``min_update_interval_us`` of
vehicle time), CLEARED on exit.  Never a bare bool.

:class:`LinkAlarmMonitor` turns link statistics into ``AlarmKind.LINK`` alarms on
``ChannelId("link", vehicle, <condition>)`` channels, so packet loss, CRC errors, a stale
stream or an autopilot reboot can never be mistaken for a sensor fault. Each of them clears
when its condition ends: loss is measured over a sliding window (not since the start), the
holds after a CRC error or a reboot run in vehicle time and restart when the clock steps back,
and a shared system id is flagged only while the second sender is heard.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass
from enum import StrEnum

from gcs_monitor.core.params import param
from gcs_monitor.core.types import ChannelId
from gcs_monitor.fdi.events import OBSERVED_TYPES, AlarmEvent, AlarmKind, AlarmState, FaultType


class ChannelAlarm(StrEnum):
    """State of one channel's alarm."""

    NORMAL = "normal"
    ACTIVE = "active"


@dataclass(frozen=True, slots=True)
class AlarmParams:
    """UPDATED-event policy (project choice: at most 2 updates/s, on a 25 % change).

    update_rel_change : relative magnitude change that warrants an UPDATED event
    min_update_interval_us : minimum vehicle time between two events of one channel, µs
    """

    update_rel_change: float = 0.25
    min_update_interval_us: int = 500_000


class AlarmStateMachine:
    """Raise / update / clear one channel's alarm from per-sample decisions."""

    __slots__ = ("channel", "kind", "estimator", "vehicle", "p", "state", "_type", "_mag",
                 "_conf", "_last_event_us")

    def __init__(
        self,
        channel: ChannelId,
        kind: AlarmKind,
        estimator: str,
        *,
        params: AlarmParams | None = None,
        vehicle: int = 1,
    ) -> None:
        self.channel = channel
        self.kind = kind
        self.estimator = estimator
        self.vehicle = vehicle
        self.p = params if params is not None else AlarmParams()
        self.state = ChannelAlarm.NORMAL
        self._type = FaultType.UNKNOWN
        self._mag = math.nan
        self._conf = 0.0
        self._last_event_us = -(1 << 62)

    @property
    def active(self) -> bool:
        return self.state is ChannelAlarm.ACTIVE

    def _event(self, t_us: int, state: AlarmState, fault_type: FaultType, magnitude: float,
               rms: float, threshold: float, message: str) -> AlarmEvent:
        self._last_event_us = t_us
        return AlarmEvent(t_us=t_us, channel=self.channel, state=state, kind=self.kind,
                          fault_type=fault_type, magnitude=magnitude, residual_rms=rms,
                          threshold=threshold, estimator=self.estimator, message=message,
                          vehicle=self.vehicle, confidence=self._conf)

    def step(
        self,
        t_us: int,
        faulty: bool,
        *,
        fault_type: FaultType = FaultType.UNKNOWN,
        magnitude: float = math.nan,
        rms: float = math.nan,
        threshold: float = math.nan,
        message: str = "",
        confidence: float | None = None,
    ) -> list[AlarmEvent]:
        """Advance one sample; return the transitions (0 or 1 event).

        ``confidence`` in ``fault_type`` (see :class:`AlarmEvent`); None: 1 for an observed
        type (link, no_data), else 0. A change of confidence alone is no UPDATED event; the
        next event carries it.
        """
        if faulty:
            if confidence is None:
                confidence = 1.0 if fault_type in OBSERVED_TYPES else 0.0
            self._conf = min(max(confidence, 0.0), 1.0)
        if self.state is ChannelAlarm.NORMAL:
            if not faulty:
                return []
            self.state = ChannelAlarm.ACTIVE
            self._type = fault_type
            self._mag = magnitude
            return [self._event(t_us, AlarmState.RAISED, fault_type, magnitude, rms, threshold,
                                message)]
        if not faulty:
            self.state = ChannelAlarm.NORMAL
            return [self._event(t_us, AlarmState.CLEARED, self._type, self._mag, rms, threshold,
                                message)]
        if t_us - self._last_event_us < self.p.min_update_interval_us:
            return []
        changed = fault_type is not self._type
        if not changed and math.isfinite(magnitude):
            ref = self._mag
            if not math.isfinite(ref):
                changed = True
            else:
                changed = abs(magnitude - ref) > self.p.update_rel_change * max(abs(ref), 1e-300)
        if not changed:
            return []
        self._type = fault_type
        self._mag = magnitude
        return [self._event(t_us, AlarmState.UPDATED, fault_type, magnitude, rms, threshold,
                            message)]


@dataclass(frozen=True, slots=True)
class LinkAlarmParams:
    """Link-health thresholds (project choices).

    max_loss_pct : packet loss (from sequence gaps) above which LINK/loss is raised, %
    loss_clear_pct : loss below which it clears (hysteresis), %
    loss_window_s : the loss is that of the last this many seconds of vehicle time, s
    crc_hold_s : LINK/crc stays raised this long after the last new CRC error, s
    max_stream_age_s : LINK/stale when no message has arrived for this long, s
    reboot_hold_s : LINK/reboot is shown for this long after a detected reboot, s
    check_period_s : how often the link statistics are checked, s
    """

    max_loss_pct: float = 5.0
    loss_clear_pct: float = 2.0
    loss_window_s: float = param(10.0, "packet loss is measured over this much recent vehicle "
                                 "time, so LINK/loss clears once the link has recovered",
                                 positive=True)
    crc_hold_s: float = 5.0
    max_stream_age_s: float = 1.0
    reboot_hold_s: float = 5.0
    check_period_s: float = param(1.0, "link statistics are turned into LINK alarms this often "
                                  "(vehicle time)", positive=True)


_US_PER_S = 1_000_000


class LinkAlarmMonitor:
    """LINK alarms from link statistics; never reported as sensor faults.

    ``step(t_us, stats)`` reads these keys from ``stats`` (missing keys are skipped):

    - ``lost``, ``messages`` : cumulative lost and received packets; the loss is taken over
      the last ``loss_window_s`` (otherwise ``loss_pct``, a loss % as given, is used)
    - ``crc_errors`` : cumulative CRC / parse error count
    - ``stream_age_s`` : time since the last message of this vehicle, s
    - ``boot_count`` : cumulative number of reboots seen (e.g. from a drop of
      ``time_boot_ms``); any increase is a reboot, shown for ``reboot_hold_s``
    - ``duplicate_sysid`` : 1 while two senders share this system id (interleaved sequence
      numbers, conflicting clocks or heartbeats; see ``LinkStats``), else 0

    Channels: ``ChannelId("link", vehicle, "loss" | "crc" | "stale" | "reboot" |
    "duplicate_sysid")``. ``t_us`` may step back (an autopilot reboot restarts the vehicle
    clock): the loss window and the CRC and reboot holds then restart at the new ``t_us``, so
    each alarm still clears a hold after its last cause.
    """

    def __init__(self, *, params: LinkAlarmParams | None = None, vehicle: int = 1,
                 alarm: AlarmParams | None = None) -> None:
        self.p = params if params is not None else LinkAlarmParams()
        self.vehicle = vehicle
        self._sm = {
            name: AlarmStateMachine(ChannelId("link", vehicle, name), AlarmKind.LINK, "link",
                                    params=alarm, vehicle=vehicle)
            for name in ("loss", "crc", "stale", "reboot", "duplicate_sysid")
        }
        self._crc_prev: float | None = None
        self._crc_last_us: int | None = None
        self._boot_prev: float | None = None
        self._boot_last_us: int | None = None
        self._loss_active = False
        self._loss_hist: deque[tuple[int, float, float]] = deque()  # (t_us, messages, lost)
        self._last_t_us: int | None = None

    def _recent_loss_pct(self, t_us: int, messages: float, lost: float) -> float:
        """Loss over the last ``loss_window_s``: lost / (received + lost) since the oldest
        snapshot inside the window (a late packet is taken back off ``lost``: clipped at 0)."""
        hist = self._loss_hist
        hist.append((t_us, messages, lost))
        window_us = self.p.loss_window_s * _US_PER_S
        while len(hist) > 1 and t_us - hist[1][0] >= window_us:
            hist.popleft()
        _, m0, l0 = hist[0]
        d_lost = max(lost - l0, 0.0)
        total = (messages - m0) + d_lost
        return 100.0 * d_lost / total if total > 0 else 0.0

    def step(self, t_us: int, stats: Mapping[str, float]) -> list[AlarmEvent]:
        events: list[AlarmEvent] = []
        lt = FaultType.LINK
        if self._last_t_us is not None and t_us < self._last_t_us:
            # the vehicle clock stepped back (reboot): windows and holds restart on the new clock
            self._loss_hist.clear()
            if self._crc_last_us is not None:
                self._crc_last_us = t_us
            if self._boot_last_us is not None:
                self._boot_last_us = t_us
        self._last_t_us = t_us
        if "lost" in stats and "messages" in stats:
            loss: float | None = self._recent_loss_pct(t_us, float(stats["messages"]),
                                                       float(stats["lost"]))
        else:
            loss = float(stats["loss_pct"]) if "loss_pct" in stats else None
        if loss is not None:
            if self._loss_active:
                self._loss_active = loss >= self.p.loss_clear_pct
            else:
                self._loss_active = loss > self.p.max_loss_pct
            events += self._sm["loss"].step(t_us, self._loss_active, fault_type=lt,
                                            magnitude=loss, threshold=self.p.max_loss_pct,
                                            message=f"packet loss {loss:.1f} %")
        if "crc_errors" in stats:
            crc = float(stats["crc_errors"])
            if self._crc_prev is not None and crc > self._crc_prev:
                self._crc_last_us = t_us
            self._crc_prev = crc
            on = self._crc_last_us is not None and (
                t_us - self._crc_last_us < self.p.crc_hold_s * _US_PER_S)
            events += self._sm["crc"].step(t_us, on, fault_type=lt, magnitude=crc,
                                           message=f"{crc:.0f} CRC errors")
        if "stream_age_s" in stats:
            age = float(stats["stream_age_s"])
            events += self._sm["stale"].step(t_us, age > self.p.max_stream_age_s, fault_type=lt,
                                             magnitude=age, threshold=self.p.max_stream_age_s,
                                             message=f"no data for {age:.1f} s")
        if "boot_count" in stats:
            boots = float(stats["boot_count"])
            if self._boot_prev is not None and boots > self._boot_prev:
                self._boot_last_us = t_us
            self._boot_prev = boots
            on = self._boot_last_us is not None and (
                t_us - self._boot_last_us < self.p.reboot_hold_s * _US_PER_S)
            events += self._sm["reboot"].step(t_us, on, fault_type=lt, magnitude=boots,
                                              message="autopilot reboot")
        if "duplicate_sysid" in stats:
            dup = bool(stats["duplicate_sysid"])
            events += self._sm["duplicate_sysid"].step(
                t_us, dup, fault_type=lt, magnitude=float(dup),
                message=f"two senders use system id {self.vehicle}")
        return events
