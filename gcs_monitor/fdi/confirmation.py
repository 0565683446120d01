"""n_D-of-N_eval fault confirmation with hysteresis and optional latching (Wan2018 sec. III-A).

Wan2018 declares sensor i faulty when ``J_k > J_th`` for n_D times during the past window
``[k - N_eval + 1, k]`` and then removes it from the fusion (eq. 19) and from the output
vector (Table I) for the rest of the run: the paper never re-admits a sensor, so the
Wan2018 scheme latches (``latch=True``).  For channels whose faults can disappear (an
estimator's reconstructed fault returning to zero) ``latch=False`` clears the decision
after ``clear_n`` consecutive samples with ``J < clear_ratio * J_th`` (hysteresis: the
clear level sits below the raise level, so a J hovering at the threshold cannot toggle).

Wan2018 does not publish n_D.  The default here is n_D = N_eval / 2 = 5: a single
noise spike enters the RMS window for N_eval samples, so with n_D = 1 one outlier above
``sqrt(N_eval) * J_th`` would confirm on its own; n_D = 5 requires J to stay above the
threshold for half the window, at a cost of 4 samples of delay.
"""

from __future__ import annotations

from dataclasses import dataclass

from gcs_monitor.fdi.residuals import WAN2018_N_EVAL


@dataclass(frozen=True, slots=True)
class ConfirmationParams:
    """Detection confirmation (Wan2018 sec. III-A; n_D not given there, see module doc).

    detect_n : n_D, exceedances required within the last ``eval_n`` samples
    eval_n : N_eval, length of the confirmation window (Wan2018: 10)
    clear_ratio : clear level as a fraction of J_th (hysteresis), in (0, 1]
    clear_n : consecutive samples below the clear level needed to clear
    latch : keep a declared fault for good (Wan2018 behaviour)
    """

    detect_n: int = WAN2018_N_EVAL // 2
    eval_n: int = WAN2018_N_EVAL
    clear_ratio: float = 0.5
    clear_n: int = 5 * WAN2018_N_EVAL
    latch: bool = True

    def __post_init__(self) -> None:
        if not 1 <= self.detect_n <= self.eval_n:
            raise ValueError(f"need 1 <= detect_n <= eval_n, got {self.detect_n}, {self.eval_n}")
        if not 0.0 < self.clear_ratio <= 1.0:
            raise ValueError(f"clear_ratio must be in (0, 1], got {self.clear_ratio}")
        if self.clear_n < 1:
            raise ValueError(f"clear_n must be >= 1, got {self.clear_n}")


class Confirmation:
    """Declare/clear one channel's fault from its RMS sequence (n_D-of-N_eval + hysteresis).

    ``update(J, J_th)`` returns the confirmed fault state after this sample.  The
    exceedance window keeps counting while the fault is declared, so after a clear a new
    raise again needs n_D fresh exceedances.
    """

    __slots__ = ("p", "_win", "_idx", "_exceed", "_faulty", "_below", "_latched")

    def __init__(self, params: ConfirmationParams | None = None) -> None:
        self.p = params if params is not None else ConfirmationParams()
        self._win = [False] * self.p.eval_n
        self._idx = 0
        self._exceed = 0
        self._faulty = False
        self._below = 0
        self._latched = False

    @property
    def faulty(self) -> bool:
        return self._faulty

    @property
    def exceed_count(self) -> int:
        """Exceedances in the current N_eval window."""
        return self._exceed

    def update(self, rms: float, threshold: float) -> bool:
        """Push one RMS value J_k (SI) against J_th (SI); return the confirmed state."""
        exceeded = rms > threshold
        i = self._idx
        if self._win[i] != exceeded:
            self._exceed += 1 if exceeded else -1
            self._win[i] = exceeded
        i += 1
        self._idx = 0 if i == self.p.eval_n else i
        if not self._faulty:
            if self._exceed >= self.p.detect_n:
                self._faulty = True
                self._below = 0
                self._latched = self.p.latch
        elif not self._latched:
            if rms < self.p.clear_ratio * threshold:
                self._below += 1
                if self._below >= self.p.clear_n:
                    self._faulty = False
                    self._below = 0
            else:
                self._below = 0
        return self._faulty

    def reset(self) -> None:
        self._win = [False] * self.p.eval_n
        self._idx = 0
        self._exceed = 0
        self._faulty = False
        self._below = 0
        self._latched = False
