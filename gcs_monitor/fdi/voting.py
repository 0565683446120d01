"""Adaptive weighted fusion of redundant sensors (Wan2018 eq. 19), output configurations
(Wan2018 Table I), and the median / majority-vote helpers used by the baselines.

Plain Python floats and lists: a redundant set has 2-4 instances and numpy's per-call
overhead (~1 µs) would dominate at that size.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from enum import StrEnum


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


def weighted_fusion(values: Sequence[float], weights: Sequence[float]) -> float:
    """Weighted mean ``sum beta_i * y_i`` (Wan2018 eq. 19); NaN if all weights are 0."""
    acc = 0.0
    total = 0.0
    for v, w in zip(values, weights, strict=True):
        if w > 0.0:
            acc += w * v
            total += w
    return acc / total if total > 0.0 else math.nan


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


def majority_vote(
    values: Sequence[float], usable: Sequence[bool], tolerance: float
) -> list[bool]:
    """Majority vote: instance i is kept when it and the usable instances within
    ``tolerance`` (SI) of it form a strict majority of the usable instances.
    Returns (n,) agree flags (False where unusable).

    With three instances a single outlier is voted out; with two instances in the same
    wrong place the good one is the one voted out (the failure Wan2018 sec. I describes).
    """
    n = len(values)
    idx = [i for i in range(n) if usable[i]]
    out = [False] * n
    for i in idx:
        others = [j for j in idx if j != i]
        agree = sum(1 for j in others if abs(values[i] - values[j]) <= tolerance)
        out[i] = 2 * (1 + agree) > len(idx)
    return out


class OutputConfiguration(StrEnum):
    """Wan2018 Table I: which fused air-data outputs enter the estimator's output (20d).

    The table, read column by column (its layout is garbled in the text copy, the rows are
    reconstructed from sec. III-C and the observability remarks):

    - I   (N_alpha^f < 3, N_vc^f < 3): y = [V_g,m, V_z,m, alpha_m, V_c,m]
    - II  (N_alpha^f = 3, N_vc^f < 3): y = [V_g,m, V_z,m, V_c,m]
    - III (N_alpha^f < 3, N_vc^f = 3): y = [V_g,m, V_z,m, alpha_m]
    - IV  (N_alpha^f = 3, N_vc^f = 3): y = [V_g,m, V_z,m]

    So a set keeps feeding its fused value while at least one instance is healthy, whatever
    the number of faulty ones; only when all are faulty is it dropped and its value comes
    from the model estimate alone (virtual sensor).
    """

    I = "I"  # noqa: E741  (the paper's name)
    II = "II"
    III = "III"
    IV = "IV"


def output_configuration(aoa_lost: bool, cas_lost: bool) -> OutputConfiguration:
    """Wan2018 Table I category from whether every AoA / every CAS instance is faulty."""
    if aoa_lost:
        return OutputConfiguration.IV if cas_lost else OutputConfiguration.II
    return OutputConfiguration.III if cas_lost else OutputConfiguration.I


def output_vector_names(config: OutputConfiguration) -> tuple[str, ...]:
    """Names of the outputs in (20d) for a Table I configuration."""
    return {
        OutputConfiguration.I: ("gs_mps", "vz_mps", "aoa_rad", "cas_mps"),
        OutputConfiguration.II: ("gs_mps", "vz_mps", "cas_mps"),
        OutputConfiguration.III: ("gs_mps", "vz_mps", "aoa_rad"),
        OutputConfiguration.IV: ("gs_mps", "vz_mps"),
    }[config]


@dataclass(frozen=True, slots=True)
class SetConfiguration:
    """The per-set half of Table I: how many instances feed the fused value.

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
