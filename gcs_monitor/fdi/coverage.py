"""Coverage: how much of the recent flight a family actually judged, and the alarm when too
little.

A monitor that cannot judge must say so (design.md). Every family reports per Frame whether it
judged and, if not, why (:class:`~gcs_monitor.fdi.records.FamilyStatus`). A Frame counts as
*covered* by a family when the family judged a sample within the last ``hold_s`` (its driving
stream may be slower than the Frames: 20 Hz air data on 100 Hz Frames). The coverage is the
covered share of the Frames of the last ``window_s`` of vehicle time. The family is:

* ``unavailable`` while its inputs were never in the telemetry (a copter has no AoA vanes):
  reported, never alarmed;
* ``starting`` from its first inputs until it first judges (estimator warm-up), for at most
  ``window_s``; the start-up is not counted (the coverage window begins at the first judged
  sample, or ``window_s`` after the first inputs when it never judges);
* ``judging`` while the coverage is at least ``min_coverage``;
* ``degraded`` otherwise: a ``monitor_degraded`` alarm (never a sensor fault) is raised, with
  the reason most Frames were not judged (a Frame between two samples of a slower driving
  stream counts under the last sample's reason), and cleared once the coverage is back above
  ``clear_coverage`` (hysteresis).

Deterministic, vehicle time only.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Any

from gcs_monitor.core.params import param
from gcs_monitor.core.types import ChannelId
from gcs_monitor.fdi.alarms import AlarmParams, AlarmStateMachine
from gcs_monitor.fdi.events import AlarmEvent, AlarmKind, FaultType
from gcs_monitor.fdi.records import Coverage, FamilyStatus

US_PER_S = 1_000_000
MONITOR_KIND = "monitor"  # ChannelId(kind) of monitor_degraded alarms; axis = the family


@dataclass(frozen=True, slots=True)
class CoverageConfig:
    """When a family counts as judging, and when it is reported degraded (``[coverage]``)."""

    window_s: float = param(10.0, "span of vehicle time the coverage is measured over",
                            positive=True)
    min_coverage: float = param(0.9, "a family judging less than this share of the window "
                                "raises monitor_degraded", positive=True)
    clear_coverage: float = param(0.95, "monitor_degraded clears once the share is back above "
                                  "this", positive=True)
    hold_s: float = param(0.5, "a judged sample covers the Frames of this long after it (the "
                          "family's stream may be slower than the Frames)", positive=True)

    def __post_init__(self) -> None:
        if not 0.0 < self.min_coverage <= self.clear_coverage <= 1.0:
            raise ValueError("need 0 < min_coverage <= clear_coverage <= 1, got "
                             f"{self.min_coverage}, {self.clear_coverage}")


class FamilyCoverage:
    """Coverage and monitor_degraded alarm of one family (see the module docstring).

    The window is kept as runs of Frames in one state (covered, or not covered for one reason),
    each weighted by the vehicle time it spans (the interval since the previous Frame), so a
    Frame costs a few additions and the share is a share of time.
    """

    __slots__ = ("family", "cfg", "_window_us", "_hold_us", "_runs", "_covered_us", "_total_us",
                 "_reason_us", "_prev_t", "_last_judged_us", "_first_inputs_us", "_alarm",
                 "state", "_all_us", "_all_covered_us", "_reason_last", "_sample_reason",
                 "_sample_us")

    def __init__(self, family: str, cfg: CoverageConfig, *, vehicle: int = 1,
                 alarm: AlarmParams | None = None) -> None:
        self.family = family
        self.cfg = cfg
        self._window_us = round(cfg.window_s * US_PER_S)
        self._hold_us = round(cfg.hold_s * US_PER_S)
        # runs of the window, oldest first: [start_us, end_us, covered, reason]
        self._runs: deque[list[Any]] = deque()
        self._covered_us = 0
        self._total_us = 0
        self._reason_us: dict[str, int] = {}  # uncovered time per reason in the window
        self._prev_t: int | None = None
        self._last_judged_us: int | None = None
        self._first_inputs_us: int | None = None
        self._alarm = AlarmStateMachine(ChannelId(MONITOR_KIND, 0, family),
                                        AlarmKind.MONITOR_DEGRADED, family, params=alarm,
                                        vehicle=vehicle)
        self.state = "unavailable"
        self._all_us = 0  # since the family first judged (or was first due to)
        self._all_covered_us = 0
        self._reason_last = "no inputs yet"
        # the latest Frame that carried a sample of the family's driving stream: why it was not
        # judged, and when (a Frame between two samples says nothing new about why)
        self._sample_reason = ""
        self._sample_us = -1

    def recent(self) -> float:
        """Share of the window's time judged (NaN before anything was counted)."""
        if self._total_us:
            return self._covered_us / self._total_us
        return math.nan if not self._runs else (1.0 if self._runs[-1][2] else 0.0)

    def reason(self) -> str:
        """The reason most of the window's uncovered time had."""
        if not self._reason_us:
            return "" if self.state != "unavailable" else self._reason_last
        return max(self._reason_us.items(), key=lambda kv: kv[1])[0]

    @property
    def coverage(self) -> Coverage:
        if self.state in ("unavailable", "starting"):
            return Coverage(self.family, self.state, math.nan, math.nan, self._reason_last)
        overall = self._all_covered_us / self._all_us if self._all_us else self.recent()
        return Coverage(self.family, self.state, self.recent(), overall, self.reason())

    def step(self, st: FamilyStatus) -> list[AlarmEvent]:
        """One Frame's status of the family; returns the monitor_degraded transitions."""
        t = st.t_us
        if self._first_inputs_us is None:
            if not st.inputs:
                self._reason_last = st.reason or "inputs missing"
                return []
            self._first_inputs_us = t
        if st.judged:
            self._last_judged_us = t
        last = self._last_judged_us
        if last is None and t - self._first_inputs_us < self._window_us:
            # start-up (estimator warm-up): not a loss of coverage, not counted
            self.state = "starting"
            self._reason_last = st.reason or "starting"
            return []
        covered = last is not None and t - last <= self._hold_us
        if st.sample:
            self._sample_reason, self._sample_us = st.reason, t
        if covered:
            reason = ""
        elif not st.sample and self._sample_reason and t - self._sample_us <= self._hold_us:
            # between two samples of a stream slower than the Frames ("between observer
            # steps", "no new air data"): the uncovered time is the last sample's reason's
            reason = self._sample_reason
        else:
            reason = st.reason or "not judged"
        prev = self._prev_t
        self._prev_t = t
        dt = t - prev if prev is not None and t > prev else 0
        runs = self._runs
        if runs and runs[-1][2] == covered and runs[-1][3] == reason:
            runs[-1][1] = t
        else:
            runs.append([prev if prev is not None else t, t, covered, reason])
        if dt:
            self._total_us += dt
            self._all_us += dt
            if covered:
                self._covered_us += dt
                self._all_covered_us += dt
            else:
                self._reason_us[reason] = self._reason_us.get(reason, 0) + dt
            self._evict(t - self._window_us)
        share = self.recent()
        active = self._alarm.active
        degraded = share < (self.cfg.clear_coverage if active else self.cfg.min_coverage)
        events: list[AlarmEvent] = []
        if degraded != active:
            msg = (f"{self.family} judged {100 * share:.0f} % of the last "
                   f"{self.cfg.window_s:g} s: {self.reason()}" if degraded else
                   f"{self.family} judging again ({100 * share:.0f} %)")
            events = self._alarm.step(t, degraded, fault_type=FaultType.UNKNOWN,
                                      magnitude=share, rms=math.nan,
                                      threshold=self.cfg.min_coverage, message=msg)
            active = self._alarm.active
        self.state = "degraded" if active else "judging"
        return events

    def _evict(self, horizon: int) -> None:
        """Drop the time before ``horizon`` from the window's runs and sums."""
        runs = self._runs
        while runs and runs[0][0] < horizon:
            r = runs[0]
            cut = min(r[1], horizon) - r[0]
            if cut > 0:
                self._total_us -= cut
                if r[2]:
                    self._covered_us -= cut
                else:
                    left = self._reason_us[r[3]] - cut
                    if left > 0:
                        self._reason_us[r[3]] = left
                    else:
                        del self._reason_us[r[3]]
            if r[1] <= horizon:
                runs.popleft()
            else:
                r[0] = horizon
                break
