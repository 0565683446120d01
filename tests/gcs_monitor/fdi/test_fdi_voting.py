"""Adaptive weights (Wan2018 eq. 19), the per-set Table I label, the median, consensus."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gcs_monitor.fdi.isolation import consensus_residuals
from gcs_monitor.fdi.voting import SetConfiguration, adaptive_weights, median_of


def test_eq19_hand_values() -> None:
    # J = 1, 2, 4 -> 1/J^2 = 1, 1/4, 1/16; sum 21/16 -> beta = 16/21, 4/21, 1/21
    w = adaptive_weights([1.0, 2.0, 4.0], [True] * 3, threshold=10.0, rms_floor=0.1)
    assert w == pytest.approx([16 / 21, 4 / 21, 1 / 21], rel=1e-15)


def test_eq19_excludes_above_threshold_and_declared() -> None:
    # J_3 > J_th: not in the set of eq. 19; instance 2 declared faulty: not eligible
    w = adaptive_weights([1.0, 1.0, 5.0, 2.0], [True, False, True, True], 4.0, 0.1)
    assert w == pytest.approx([0.8, 0.0, 0.0, 0.2], rel=1e-15)


def test_eq19_floor_and_fallback() -> None:
    # J = 0 (e.g. the median instance) is floored: equal weights within the noise level
    assert adaptive_weights([0.0, 0.5, 1.0], [True] * 3, 10.0, 1.0) == pytest.approx([1 / 3] * 3)
    # all momentarily above J_th but none declared: fall back to 1/J^2 over the eligible
    assert adaptive_weights([20.0, 40.0], [True, True], 10.0, 1.0) == pytest.approx([0.8, 0.2])
    assert adaptive_weights([1.0, 1.0], [False, False], 10.0, 1.0) == [0.0, 0.0]


@settings(max_examples=100, deadline=None)
@given(st.lists(st.floats(1e-3, 1e3), min_size=1, max_size=6))
def test_weights_sum_to_one_and_decrease_with_rms(js: list[float]) -> None:
    w = adaptive_weights(js, [True] * len(js), 1e9, 1e-6)
    assert sum(w) == pytest.approx(1.0, rel=1e-12)
    order = sorted(range(len(js)), key=lambda i: js[i])
    assert all(w[order[k]] >= w[order[k + 1]] - 1e-15 for k in range(len(js) - 1))


@settings(max_examples=100, deadline=None)
@given(st.lists(st.floats(-1e6, 1e6), min_size=1, max_size=7))
def test_median_matches_sorted(xs: list[float]) -> None:
    s = sorted(xs)
    n = len(s)
    ref = s[n // 2] if n % 2 else 0.5 * (s[n // 2 - 1] + s[n // 2])
    assert median_of(xs) == ref


def test_table1_set_configuration_labels() -> None:
    assert SetConfiguration(2, 3, False, False).label == "fused 2/3"
    assert SetConfiguration(0, 3, True, True).label == "lost: virtual"
    assert SetConfiguration(0, 3, True, False).label == "lost: none"


def test_consensus_rules() -> None:
    nan = math.nan
    c, r = consensus_residuals([1.0, 2.0, 9.0], [True] * 3, [True] * 3)
    assert c == 2.0 and r == [-1.0, 0.0, 7.0]
    # two healthy: full difference for both, the latched one against their mean
    c, r = consensus_residuals([1.0, 2.0, 9.0], [True] * 3, [True, True, False])
    assert c == 1.5 and r == [-1.0, 1.0, 7.5]
    c, r = consensus_residuals([1.0, 2.0, 9.0], [True] * 3, [False, True, False])
    assert c == 2.0 and math.isnan(r[1]) and r[0] == -1.0 and r[2] == 7.0
    c, r = consensus_residuals([1.0, 2.0], [False, False], [False, False])
    assert math.isnan(c) and all(x != x for x in r)
    del nan
