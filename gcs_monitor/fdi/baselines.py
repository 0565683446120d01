"""Baselines a user would otherwise rely on: median (mid-value) selection with a
persistence-confirmed comparison monitor, as in industrial triplex voting (Wan2018 sec. I,
sec. II "majority voting scheme"), and the same comparison with a raw fixed threshold and
no persistence.

Same ``step(t_us, measured, valid, reference)`` interface as
:class:`~gcs_monitor.fdi.monitor.RedundantSetMonitor` so the evaluation harness can run
them side by side; ``reference`` is ignored (the baselines know no model).

Rule: instance i is declared faulty when ``|y_i - median(remaining)| > threshold`` for
``persistence_n`` consecutive samples; with two faulty instances on the same side the
median follows them and the good instance is the one declared faulty.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from gcs_monitor.core.types import ChannelId
from gcs_monitor.fdi.alarms import AlarmParams, AlarmStateMachine
from gcs_monitor.fdi.events import (
    SET_INSTANCE,
    AlarmEvent,
    AlarmKind,
    FaultType,
    SetStatus,
)
from gcs_monitor.fdi.voting import median_of


@dataclass(frozen=True, slots=True)
class MedianVoteParams:
    """Comparison-monitor baseline.

    threshold : allowed |y_i - median|, SI
    persistence_n : consecutive exceedances before exclusion (1 = raw fixed threshold)
    latch : excluded instances stay excluded (usual in flight-control voters)
    """

    threshold: float
    persistence_n: int = 10
    latch: bool = True
    alarm: AlarmParams = field(default_factory=AlarmParams)


class MedianVoteMonitor:
    """Median selection + comparison monitor with persistence (industry baseline)."""

    def __init__(self, name: str, n: int, params: MedianVoteParams, *,
                 estimator: str = "median_vote", vehicle: int = 1, axis: str = "") -> None:
        self.name = name
        self.n = n
        self.p = params
        self._count = [0] * n
        self._faulty = [False] * n
        self._alarm = [AlarmStateMachine(ChannelId(name, i, axis), AlarmKind.SENSOR_FAULT,
                                         estimator, params=params.alarm, vehicle=vehicle)
                       for i in range(n)]
        self._set_alarm = AlarmStateMachine(ChannelId(name, SET_INSTANCE, axis),
                                            AlarmKind.SET_LOST, estimator, params=params.alarm,
                                            vehicle=vehicle)

    def step(
        self,
        t_us: int,
        measured: np.ndarray | Sequence[float],
        valid: np.ndarray | Sequence[bool],
        reference: float | None = None,
    ) -> tuple[SetStatus, list[AlarmEvent]]:
        del reference  # the baseline has no model
        m = measured.tolist() if isinstance(measured, np.ndarray) else list(measured)
        vl = valid.tolist() if isinstance(valid, np.ndarray) else list(valid)
        rng = range(self.n)
        usable = [vl[i] and m[i] == m[i] for i in rng]
        # latched voters drop excluded instances from the median; a non-latching voter
        # keeps mid-value selecting over every usable instance
        latch = self.p.latch
        remaining = [usable[i] and not (latch and self._faulty[i]) for i in rng]
        med = median_of([m[i] for i in rng if remaining[i]])
        th = self.p.threshold
        dev = [abs(m[i] - med) if usable[i] and med == med else math.nan for i in rng]
        for i in rng:
            if dev[i] != dev[i]:
                continue
            if dev[i] > th:
                self._count[i] += 1
                if self._count[i] >= self.p.persistence_n:
                    self._faulty[i] = True
            else:
                self._count[i] = 0
                if self._faulty[i] and not self.p.latch:
                    self._faulty[i] = False
        events: list[AlarmEvent] = []
        for i in rng:
            f = self._faulty[i]
            if f != self._alarm[i].active:
                events += self._alarm[i].step(t_us, f, fault_type=FaultType.UNKNOWN,
                                              magnitude=m[i] - med if f else math.nan,
                                              rms=dev[i], threshold=th)
        lost = all(self._faulty)
        if lost != self._set_alarm.active:
            events += self._set_alarm.step(t_us, lost, rms=math.nan, threshold=th)
        eligible = [usable[i] and not self._faulty[i] for i in rng]
        sel = median_of([m[i] for i in rng if eligible[i]])
        k = sum(eligible)
        w = [1.0 / k if eligible[i] else 0.0 for i in rng] if k else [0.0] * self.n
        status = SetStatus(name=self.name, t_us=t_us, measured=tuple(m), reference=med,
                           fused=sel, weights=tuple(w), rms=tuple(dev), threshold=th,
                           faulty=tuple(self._faulty),
                           configuration=f"median {k}/{self.n}" if k else "lost: none")
        return status, events


def fixed_threshold_monitor(name: str, n: int, threshold: float, **kw: object) -> MedianVoteMonitor:
    """Raw fixed threshold on the difference to the median, no persistence, no latch."""
    return MedianVoteMonitor(name, n, MedianVoteParams(threshold=threshold, persistence_n=1,
                                                       latch=False), **kw)  # type: ignore[arg-type]
