"""Adaptive weights for the fusion of redundant sensors (Wan2018 eq. 19), the per-set output
configuration (Wan2018 Table I), and the median used by the isolation and the baselines.

Plain Python floats and lists: a redundant set has 2-4 instances and numpy's per-call
overhead (~1 µs) would dominate at that size.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass


def rms_floor_from_noise(noise_sigma: float) -> float:
    """Floor on J in the weights of Wan2018 eq. 19, from the measurement noise 1-sigma (SI).

    A healthy residual (measurement minus reference, or minus the set median) has an RMS
    of at least the sensor noise sigma.  Flooring J at sigma keeps 1/J^2 finite (a stuck or
    noiseless instance would otherwise take all the weight) and makes healthy instances
    share the weight equally; only instances whose J rises clearly above the noise level
    lose weight, which is the behaviour eq. 19 is for.
    """
    if not noise_sigma > 0.0:
        raise ValueError(f"noise_sigma must be > 0, got {noise_sigma}")
    return noise_sigma


def adaptive_weights(
    rms: Sequence[float],
    eligible: Sequence[bool],
    threshold: float,
    rms_floor: float,
) -> list[float]:
    """Weights beta^(i) of Wan2018 eq. 19.

    ``beta_i = (1/J_i^2) / sum_{j in S} (1/J_j^2)`` over ``S = {j eligible : J_j <= J_th}``,
    with ``J`` floored at ``rms_floor``; weights outside S are 0.  Eligible means valid and
    not declared faulty (the paper's set uses the instantaneous J only; declared faults are
    also removed because Wan2018 removes isolated sensors for good).  If every eligible
    instance is momentarily above J_th but none is confirmed yet, eq. 19 is undefined; we
    then fuse all eligible instances with the same 1/J^2 rule rather than output nothing.
    Returns all zeros when nothing is eligible.

    Parameters
    ----------
    rms : (n,) residual RMS J per instance (Wan2018 eq. 18), SI
    eligible : (n,) valid and not declared faulty
    threshold : J_th, SI
    rms_floor : lower bound on J inside 1/J^2, SI (see :func:`rms_floor_from_noise`)
    """
    n = len(rms)
    inv = [0.0] * n
    total = 0.0
    for i in range(n):
        if eligible[i] and rms[i] <= threshold:
            j = rms[i] if rms[i] > rms_floor else rms_floor
            w = 1.0 / (j * j)
            inv[i] = w
            total += w
    if total == 0.0:
        for i in range(n):
            if eligible[i]:
                j = rms[i] if rms[i] > rms_floor else rms_floor
                w = 1.0 / (j * j)
                inv[i] = w
                total += w
    if total == 0.0:
        return inv
    return [w / total for w in inv]


def median_of(values: Sequence[float]) -> float:
    """Median of a short list (mean of the two middle values for even length); NaN if empty."""
    n = len(values)
    if n == 0:
        return math.nan
    if n == 1:
        return values[0]
    if n == 2:
        return 0.5 * (values[0] + values[1])
    if n == 3:
        a, b, c = values
        if a > b:
            a, b = b, a
        if b > c:
            b = c
        return a if a > b else b
    s = sorted(values)
    h = n // 2
    return s[h] if n % 2 else 0.5 * (s[h - 1] + s[h])


@dataclass(frozen=True, slots=True)
class SetConfiguration:
    """The per-set half of Wan2018 Table I: how many instances feed the fused value.

    Table I (its layout is garbled in the text copy; the rows are reconstructed from sec. III-C
    and the observability remarks) selects the estimator's output (20d) by which sets are lost:
    I  [V_g, V_z, alpha, V_c] (neither set lost), II [V_g, V_z, V_c] (every AoA instance
    faulty), III [V_g, V_z, alpha] (every CAS instance faulty), IV [V_g, V_z] (both). So a set
    keeps feeding its fused value while at least one instance is healthy, whatever the number
    of faulty ones; only when all are faulty is it dropped and the model estimate alone stands
    in for it (virtual sensor).

    ``label`` is what :class:`~gcs_monitor.fdi.events.SetStatus.configuration` carries:
    ``"fused k/n"`` while at least one instance is healthy, ``"lost: virtual"`` when all are
    faulty and a model reference replaces the set, ``"lost: none"`` when all are faulty and
    no reference exists (fused value NaN).
    """

    n_healthy: int
    n_total: int
    lost: bool
    has_reference: bool

    @property
    def label(self) -> str:
        if not self.lost:
            return f"fused {self.n_healthy}/{self.n_total}"
        return "lost: virtual" if self.has_reference else "lost: none"
