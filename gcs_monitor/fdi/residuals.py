"""Residual RMS over a sliding window (Wan2018 eq. 18), O(1) per sample.

The window is a ring buffer of squared residuals with a running sum.  Adding and
subtracting squares in floating point lets the running sum drift away from the exact
sum (catastrophic cancellation after a large fault leaves the window), so the sum is
recomputed exactly from the buffer once per ``recompute_every`` samples; between two
recomputes the error is bounded by a few ulps of the largest square seen.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

WAN2018_N_EVAL = 10  # residual evaluation window length (Wan2018 sec. V, "N_eval is set to 10")


@dataclass(frozen=True, slots=True)
class RmsWindowParams:
    """Residual evaluation window (Wan2018 eq. 18).

    rms_window_n : N_eval, samples in the window (Wan2018: 10)
    recompute_every_n : exact re-summation period of the running sum, in samples
    """

    rms_window_n: int = WAN2018_N_EVAL
    recompute_every_n: int = 1000

    def __post_init__(self) -> None:
        if self.rms_window_n < 1:
            raise ValueError(f"rms_window_n must be >= 1, got {self.rms_window_n}")
        if self.recompute_every_n < 1:
            raise ValueError(f"recompute_every_n must be >= 1, got {self.recompute_every_n}")


class ResidualRms:
    """Sliding-window RMS of one residual signal (Wan2018 eq. 18).

    ``J_k = sqrt(1/N_eval * sum_{j=k-N_eval+1}^{k} r_j^2)``.  Before N_eval samples have
    arrived the sum runs over the samples seen so far and is still divided by N_eval, so a
    short start-up never inflates J (it under-estimates during the first N_eval - 1
    samples, which can only delay, never cause, a detection).

    A non-finite residual is not allowed into the window (it would poison the running sum
    for good): call :meth:`skip` for an invalid sample instead, which leaves J unchanged.
    """

    __slots__ = ("_buf", "_n", "_idx", "_sum", "_count", "_since_recompute", "_recompute")

    def __init__(self, params: RmsWindowParams | None = None) -> None:
        p = params if params is not None else RmsWindowParams()
        self._n = p.rms_window_n
        self._recompute = p.recompute_every_n
        self._buf = [0.0] * self._n
        self._idx = 0
        self._sum = 0.0
        self._count = 0
        self._since_recompute = 0

    @property
    def window_n(self) -> int:
        return self._n

    @property
    def count(self) -> int:
        """Samples in the window (saturates at N_eval)."""
        return self._count

    def update(self, residual: float) -> float:
        """Push one residual (SI) and return J_k (SI), Wan2018 eq. 18."""
        sq = residual * residual
        if sq != sq or sq == math.inf:  # NaN / inf: programming error upstream
            raise ValueError(f"non-finite residual {residual!r}; call skip() for invalid samples")
        i = self._idx
        self._sum += sq - self._buf[i]
        self._buf[i] = sq
        i += 1
        self._idx = 0 if i == self._n else i
        if self._count < self._n:
            self._count += 1
        self._since_recompute += 1
        if self._since_recompute >= self._recompute:
            self._sum = math.fsum(self._buf)
            self._since_recompute = 0
        s = self._sum
        return math.sqrt(s / self._n) if s > 0.0 else 0.0

    def value(self) -> float:
        """Current J (SI) without pushing a sample."""
        s = self._sum
        return math.sqrt(s / self._n) if s > 0.0 else 0.0

    def window(self) -> list[float]:
        """Squared residuals in the window, oldest first."""
        if self._count < self._n:
            return self._buf[: self._count]
        return self._buf[self._idx :] + self._buf[: self._idx]

    def reset(self) -> None:
        self._buf = [0.0] * self._n
        self._idx = 0
        self._sum = 0.0
        self._count = 0
        self._since_recompute = 0
