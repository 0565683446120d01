"""A fake clock for pacing code: ``monotonic()`` reads it, ``sleep()`` advances it.

Patch it over a module's ``time`` (``monkeypatch.setattr(module, "time", FakeClock())``) and the
module's schedule can be checked exactly, without waiting and without wall-time asserts.
"""

from __future__ import annotations


class FakeClock:
    """Stands in for the ``time`` module in the module under test.

    Parameters
    ----------
    t0_s : the clock's starting reading, s
    """

    def __init__(self, t0_s: float = 1000.0) -> None:
        self.now_s = t0_s

    def monotonic(self) -> float:
        return self.now_s

    def sleep(self, dt_s: float) -> None:
        assert dt_s >= 0.0, dt_s  # time.sleep rejects negative delays
        self.now_s += dt_s

    def advance(self, dt_s: float) -> None:
        """Time the caller spends working between two calls."""
        self.now_s += dt_s
