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
  the reason most Frames were not judged, and cleared once the coverage is back above
  ``clear_coverage`` (hysteresis).

Deterministic, vehicle time only.
"""

from __future__ import annotations

import math
from collections import Counter, deque
from dataclasses import dataclass

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
    """Coverage and monitor_degraded alarm of one family (see the module docstring)."""

    __slots__ = ("family", "cfg", "_window_us", "_hold_us", "_frames", "_n_covered",
                 "_last_judged_us", "_first_inputs_us", "_seen_inputs", "_reasons", "_alarm",
                 "state", "_total", "_total_covered", "_last")

    def __init__(self, family: str, cfg: CoverageConfig, *, vehicle: int = 1,
                 alarm: AlarmParams | None = None) -> None:
        self.family = family
        self.cfg = cfg
        self._window_us = round(cfg.window_s * US_PER_S)
        self._hold_us = round(cfg.hold_s * US_PER_S)
        # (t_us, covered, reason) of the Frames in the window
        self._frames: deque[tuple[int, bool, str]] = deque()
        self._n_covered = 0
        self._reasons: Counter[str] = Counter()  # reasons of the uncovered Frames in the window
        self._last_judged_us: int | None = None
        self._first_inputs_us: int | None = None
        self._seen_inputs = False
        self._alarm = AlarmStateMachine(ChannelId(MONITOR_KIND, 0, family),
                                        AlarmKind.MONITOR_DEGRADED, family, params=alarm,
                                        vehicle=vehicle)
        self.state = "unavailable"
        self._total = 0  # Frames since the family first had inputs
        self._total_covered = 0
        self._last = Coverage(family, "unavailable", math.nan, math.nan, "no inputs yet")

    @property
    def coverage(self) -> Coverage:
        return self._last

    def step(self, st: FamilyStatus) -> list[AlarmEvent]:
        """One Frame's status of the family; returns the monitor_degraded transitions."""
        t = st.t_us
        if st.inputs and not self._seen_inputs:
            self._seen_inputs = True
            self._first_inputs_us = t
        if not self._seen_inputs:
            self._last = Coverage(self.family, "unavailable", math.nan, math.nan,
                                  st.reason or "inputs missing")
            return []
        if st.judged:
            self._last_judged_us = t
        last = self._last_judged_us
        assert self._first_inputs_us is not None
        if last is None and t - self._first_inputs_us < self._window_us:
            # start-up (estimator warm-up): not a loss of coverage, not counted
            self.state = "starting"
            self._last = Coverage(self.family, "starting", math.nan, math.nan,
                                  st.reason or "starting")
            return []
        covered = last is not None and t - last <= self._hold_us
        reason = "" if covered else (st.reason or "not judged")
        frames = self._frames
        frames.append((t, covered, reason))
        if covered:
            self._n_covered += 1
        else:
            self._reasons[reason] += 1
        horizon = t - self._window_us
        while frames and frames[0][0] <= horizon:
            _, c, r = frames.popleft()
            if c:
                self._n_covered -= 1
            else:
                self._reasons[r] -= 1
                if not self._reasons[r]:
                    del self._reasons[r]
        self._total += 1
        self._total_covered += covered
        share = self._n_covered / len(frames)
        overall = self._total_covered / self._total
        why = self._reasons.most_common(1)[0][0] if self._reasons else ""
        active = self._alarm.active
        degraded = share < (self.cfg.clear_coverage if active else self.cfg.min_coverage)
        events: list[AlarmEvent] = []
        if degraded != active:
            msg = (f"{self.family} judged {100 * share:.0f} % of the last "
                   f"{self.cfg.window_s:g} s: {why}" if degraded else
                   f"{self.family} judging again ({100 * share:.0f} %)")
            events = self._alarm.step(t, degraded, fault_type=FaultType.UNKNOWN,
                                      magnitude=share, rms=math.nan,
                                      threshold=self.cfg.min_coverage, message=msg)
        self.state = "degraded" if self._alarm.active else "judging"
        self._last = Coverage(self.family, self.state, share, overall, why)
        return events
