"""Residual RMS window (Wan2018 eq. 18) and confirmation (n_D of N_eval, hysteresis, latch)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from gcs_monitor.fdi.confirmation import Confirmation, ConfirmationParams
from gcs_monitor.fdi.residuals import ResidualRms, RmsWindowParams


def test_eq18_hand_values() -> None:
    w = ResidualRms(RmsWindowParams(rms_window_n=3))
    # start-up divides by N_eval: J_1 = sqrt(9/3), J_2 = sqrt((9+16)/3)
    assert w.update(3.0) == pytest.approx(math.sqrt(3.0), rel=1e-15)
    assert w.update(4.0) == pytest.approx(math.sqrt(25.0 / 3.0), rel=1e-15)
    assert w.update(-12.0) == pytest.approx(math.sqrt(169.0 / 3.0), rel=1e-15)
    # 3.0 leaves the window: sqrt((16+144+0)/3)
    assert w.update(0.0) == pytest.approx(math.sqrt(160.0 / 3.0), rel=1e-15)
    assert w.window() == [16.0, 144.0, 0.0]


def rms_window_batch(residual: list[float] | tuple[float, ...], rms_window_n: int) -> list[float]:
    """Reference O(N * N_eval) implementation of Wan2018 eq. 18 over a whole sequence.

    Same start-up convention as :class:`ResidualRms` (divide by N_eval from the start).
    """
    out: list[float] = []
    for k in range(len(residual)):
        lo = max(0, k - rms_window_n + 1)
        out.append(math.sqrt(math.fsum(r * r for r in residual[lo : k + 1]) / rms_window_n))
    return out


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(-1e3, 1e3), min_size=1, max_size=60), st.integers(1, 12))
@example([663.0, 420.2702607004826, 0.03, 918.9594648280156, 0.0], 1)  # found by hypothesis
def test_running_equals_batch(xs: list[float], n: int) -> None:
    w = ResidualRms(RmsWindowParams(rms_window_n=n, recompute_every_n=7))
    got = np.array([w.update(x) for x in xs])
    want = np.asarray(rms_window_batch(xs, n))
    # The running sum drifts by a few ulps of the largest square between recomputes (module
    # docstring), so compare mean squares: J itself is sqrt of that and, next to J = 0, turns
    # an ulp of 918.96^2 (1.2e-10) into 1.1e-5.
    bound = 64 * np.finfo(float).eps * max(x * x for x in xs)  # 7 updates, two roundings each
    np.testing.assert_allclose(got**2, want**2, rtol=1e-9, atol=bound)


def test_recompute_kills_drift_after_large_fault() -> None:
    w = ResidualRms(RmsWindowParams(rms_window_n=10, recompute_every_n=50))
    for _ in range(10):
        w.update(1e8)  # huge fault, squares 1e16
    for _ in range(100):
        j = w.update(1e-3)
    # after the recompute the tiny residuals are measured exactly, not as 1e16 round-off
    assert j == pytest.approx(1e-3, rel=1e-12)


def test_nonfinite_rejected() -> None:
    with pytest.raises(ValueError):
        ResidualRms().update(math.nan)


def test_confirmation_counts_n_of_m() -> None:
    c = Confirmation(ConfirmationParams(detect_n=3, eval_n=5, latch=True))
    # threshold 1: exceedances at 0, 2, 6, 8; every 5-sample window holds at most 2
    out = [c.update(j, 1.0) for j in [2.0, 0.0, 2.0, 0.0, 0.0, 0.0, 2.0, 0.0, 2.0]]
    assert out == [False] * 9
    assert c.exceed_count == 2
    assert c.update(2.0, 1.0) is True  # window 5..9 = [0, 2, 0, 2, 2]: 3 exceedances
    # latched (Wan2018 keeps an isolated sensor out): zeros never clear it
    assert all(c.update(0.0, 1.0) for _ in range(100))


def test_confirmation_equal_to_threshold_is_not_exceeding() -> None:
    c = Confirmation(ConfirmationParams(detect_n=1, eval_n=1))
    assert c.update(1.0, 1.0) is False  # eq. 18 test is J > J_th, strict
    assert c.update(1.0 + 1e-12, 1.0) is True


def test_confirmation_hysteresis_clear() -> None:
    c = Confirmation(ConfirmationParams(detect_n=2, eval_n=3, clear_ratio=0.5, clear_n=3,
                                        latch=False))
    assert [c.update(j, 1.0) for j in (2.0, 2.0)] == [False, True]
    # 0.6 is below J_th but above the clear level 0.5: does not count towards clearing
    assert [c.update(j, 1.0) for j in (0.4, 0.4, 0.6, 0.4, 0.4)] == [True] * 5
    assert c.update(0.4, 1.0) is False  # third consecutive sample below 0.5
    # a new raise needs n_D fresh exceedances
    assert c.update(2.0, 1.0) is False
    assert c.update(2.0, 1.0) is True


def test_confirmation_params_validated() -> None:
    with pytest.raises(ValueError):
        ConfirmationParams(detect_n=6, eval_n=5)
