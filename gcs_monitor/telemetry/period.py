"""Measured sample period of a telemetry stream (vehicle time).

Windows and timeouts are configured in seconds and turned into sample counts with the period
the vehicle actually sends at, never with an assumed rate (style.md section 7). The period is
the median of the last intervals between sample instants, so one late or duplicated packet
does not move it.
"""

from __future__ import annotations

import bisect
import math
from collections import deque

US_PER_S = 1_000_000
PERIOD_INTERVALS = 16  # intervals the median runs over


class SamplePeriod:
    """Median interval of the last :data:`PERIOD_INTERVALS` sample instants of one stream.

    The intervals are also kept sorted (insertion into 16 values), so :meth:`seconds` is O(1):
    streams call it at every sample.
    """

    __slots__ = ("_last_us", "_dt_us", "_sorted", "_s")

    def __init__(self) -> None:
        self._last_us: int | None = None
        self._dt_us: deque[int] = deque()
        self._sorted: list[int] = []
        self._s = math.nan

    def add(self, t_us: int) -> None:
        """One sample instant (int µs); instants not after the previous one are ignored."""
        last = self._last_us
        if last is not None:
            if t_us <= last:
                return
            dt = t_us - last
            d, srt = self._dt_us, self._sorted
            if len(d) == PERIOD_INTERVALS:
                old = d.popleft()
                d.append(dt)
                if dt == old:  # a steady stream: the sorted intervals and the median stay
                    self._last_us = t_us
                    return
                del srt[bisect.bisect_left(srt, old)]
            else:
                d.append(dt)
            bisect.insort(srt, dt)
            n = len(srt)
            mid = n // 2
            us = srt[mid] if n % 2 else (srt[mid - 1] + srt[mid]) // 2
            self._s = us / US_PER_S
        self._last_us = t_us

    def gap(self) -> None:
        """The next instant does not follow the last one (an input gap, a restart): no interval
        is taken across it."""
        self._last_us = None

    @property
    def known(self) -> bool:
        return bool(self._dt_us)

    def seconds(self) -> float:
        """The measured period (s), NaN before two instants were seen."""
        return self._s

    def reset(self) -> None:
        self._last_us = None
        self._dt_us.clear()
        self._sorted.clear()
        self._s = math.nan
