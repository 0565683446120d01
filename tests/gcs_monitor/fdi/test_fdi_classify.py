"""Fault classification on hand-made residual sequences (one per fault family)."""

from __future__ import annotations

import numpy as np
import pytest

from gcs_monitor.fdi.classify import ClassifierParams, classify_residual
from gcs_monitor.fdi.events import FaultType

DT_S = 0.01
SIGMA = 0.01
P = ClassifierParams(noise_sigma=SIGMA, runaway_rate_per_s=1.0)
N = 200


def _noise(seed: int) -> np.ndarray:
    return np.random.default_rng(seed).normal(0.0, SIGMA, N)


def test_bias_step_then_flat() -> None:
    r = _noise(1)
    r[120:] += 0.3
    c = classify_residual(r, DT_S, P)
    assert c.fault_type is FaultType.BIAS
    assert c.magnitude == pytest.approx(0.3, abs=4 * SIGMA / np.sqrt(80))


def test_bias_flat_whole_window() -> None:
    c = classify_residual(_noise(2) - 0.2, DT_S, P)
    assert c.fault_type is FaultType.BIAS
    assert c.magnitude == pytest.approx(-0.2, abs=0.005)


def test_drift_and_runaway_by_rate() -> None:
    t = np.arange(N) * DT_S
    c = classify_residual(_noise(3) + 0.5 * t, DT_S, P)  # 0.5 /s < runaway 1 /s
    assert c.fault_type is FaultType.DRIFT
    assert c.rate_per_s == pytest.approx(0.5, rel=0.05)
    assert c.magnitude == pytest.approx(0.5 * t[-1], abs=0.01)
    c = classify_residual(_noise(4) - 3.0 * t, DT_S, P)
    assert c.fault_type is FaultType.RUNAWAY
    assert c.rate_per_s == pytest.approx(-3.0, rel=0.02)


def test_oscillation_amplitude_frequency() -> None:
    t = np.arange(N) * DT_S
    c = classify_residual(_noise(5) + 0.2 * np.sin(2 * np.pi * 2.5 * t), DT_S, P)
    assert c.fault_type is FaultType.OSCILLATION
    assert c.frequency_hz == pytest.approx(2.5, abs=1 / (N * DT_S))  # one FFT bin
    assert c.magnitude == pytest.approx(0.2, rel=0.05)


def test_stuck_from_measurement() -> None:
    t = np.arange(N) * DT_S
    truth = 0.1 * np.sin(2 * np.pi * 0.3 * t)
    measured = np.full(N, 0.05)
    c = classify_residual(measured - truth, DT_S, P, measured=measured)
    assert c.fault_type is FaultType.STUCK


def test_noise_increase() -> None:
    r = np.random.default_rng(6).normal(0.0, 5 * SIGMA, N)
    c = classify_residual(r, DT_S, P)
    assert c.fault_type is FaultType.NOISE
    assert c.magnitude == pytest.approx(np.sqrt(24) * SIGMA, rel=0.2)


def test_healthy_is_unknown() -> None:
    assert classify_residual(_noise(7), DT_S, P).fault_type is FaultType.UNKNOWN
