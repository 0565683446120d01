"""Fault classification on hand-made residual sequences (one per fault family)."""

from __future__ import annotations

import numpy as np
import pytest

from gcs_monitor.fdi.classify import (
    Classification,
    ClassifierParams,
    Label,
    LabelHysteresis,
    classify_residual,
    relabel_wins_n,
)
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


# -- the decision rule's refinements ------------------------------------------------------------


def test_a_ramp_starting_inside_the_window_is_a_ramp_not_a_step() -> None:
    """A runaway caught 0.3 s after its onset (30 samples of a 200-sample window): a level then
    a ramp fits it, where a straight line over the whole window did not (it used to read as a
    bias step)."""
    t = np.arange(N) * DT_S
    r = _noise(10) - 3.0 * np.maximum(0.0, t - t[170])
    c = classify_residual(r, DT_S, P)
    assert c.fault_type is FaultType.RUNAWAY
    assert c.rate_per_s == pytest.approx(-3.0, rel=0.1)


def test_a_runaway_at_its_limit_is_still_a_ramp() -> None:
    """Ramp for 1.2 s, then held at its limit: a ramp followed by a level."""
    t = np.arange(N) * DT_S
    r = _noise(11) - 3.0 * np.minimum(t, t[120])
    c = classify_residual(r, DT_S, P)
    assert c.fault_type is FaultType.RUNAWAY
    assert c.magnitude == pytest.approx(-3.0 * t[120], abs=0.01)


def test_a_bias_onset_mid_window_is_no_oscillation() -> None:
    """Detrended by a straight line, a step in mid-window leaves one sawtooth cycle whose
    spectrum can pass the oscillation test; detrended by the step it leaves noise."""
    r = _noise(12)
    r[100:] += 0.3
    c = classify_residual(r, DT_S, P)
    assert c.fault_type is FaultType.BIAS and c.confidence == 1.0


def test_confidence_is_the_closest_call() -> None:
    """A clear bias is certain; a drift at 1.2 times the runaway rate is a runaway, but the
    rate test passed by a factor 1.2 of the certain 2: confidence ln 1.2 / ln 2."""
    t = np.arange(N) * DT_S
    c = classify_residual(_noise(13) + 1.2 * t, DT_S, P)
    assert c.fault_type is FaultType.RUNAWAY
    assert c.confidence == pytest.approx(np.log(1.2) / np.log(2.0), abs=0.03)
    assert classify_residual(_noise(14), DT_S, P).confidence == 0.0  # unknown


# -- the label of an alarm (LabelHysteresis) ---------------------------------------------------


WINS_N = relabel_wins_n(P.relabel_windows, N, 50)  # 2 s windows every 0.5 s (IMU defaults)


def test_wins_needed_span_a_window_of_new_data() -> None:
    assert WINS_N == 5  # the 5th window shares no sample with the 1st
    assert relabel_wins_n(1.0, 200, 50) == relabel_wins_n(1.0, 200, 200) + 3 == 5
    assert relabel_wins_n(0.1, 200, 50) == 2


def _labels(windows: list[np.ndarray], p: ClassifierParams = P) -> list[Label]:
    """The raise on the first window, then one re-classification per window."""
    hyst = LabelHysteresis(p, WINS_N)
    out = [hyst.decide(classify_residual(windows[0], DT_S, p))]
    out += [hyst.update(classify_residual(w, DT_S, p)) for w in windows[1:]]
    return out


def test_a_bias_keeps_its_label_through_an_oscillation_looking_window() -> None:
    """A 0.3 bias; one window also carries a burst of oscillation (turbulence, a manoeuvre)
    stronger than the bias, which the classifier calls an oscillation. The label stays bias;
    its confidence shows the disagreement while it lasts."""
    t = np.arange(N) * DT_S
    windows = [_noise(20), _noise(21) + 0.3, _noise(22) + 0.3, _noise(23) + 0.3,
               _noise(24) + 0.3]
    windows[0][150:] += 0.3
    windows[2] += 0.6 * np.sin(2 * np.pi * 3.0 * t)  # 6 cycles: decisively an oscillation
    assert classify_residual(windows[2], DT_S, P).fault_type is FaultType.OSCILLATION
    labels = _labels(windows)
    assert [lab.fault_type for lab in labels] == [FaultType.BIAS] * 5
    assert labels[2].confidence == pytest.approx(labels[1].confidence * (1 - 1 / WINS_N))
    assert labels[2].magnitude == pytest.approx(0.3, abs=0.05)  # the bias' own level
    assert labels[3].confidence == 1.0


def test_a_persistent_oscillation_replaces_the_label_after_a_window_of_wins() -> None:
    t = np.arange(N) * DT_S
    osc = [_noise(30 + k) + 0.3 + 0.6 * np.sin(2 * np.pi * 3.0 * t) for k in range(WINS_N + 1)]
    first = _noise(29)
    first[150:] += 0.3
    labels = _labels([first, *osc])
    kinds = [lab.fault_type for lab in labels]
    assert kinds == [FaultType.BIAS] * WINS_N + [FaultType.OSCILLATION] * 2


def test_a_ripple_on_a_bias_is_no_oscillation() -> None:
    """A reconstructed bias that rings (a 0.1 oscillation on a 1.0 bias): periodic once
    detrended, but a small part of the fault's power. Bias."""
    t = np.arange(N) * DT_S
    c = classify_residual(_noise(35) + 1.0 + 0.1 * np.sin(2 * np.pi * 3.0 * t), DT_S, P)
    assert c.fault_type is FaultType.BIAS


def test_a_drift_that_accelerates_past_the_runaway_rate_becomes_runaway_once() -> None:
    """0.4 /s for 6 s, then 4 /s: a drift that became a runaway, a legitimate change. Windows of
    2 s every 0.5 s (the IMU defaults); the label changes exactly once and never back."""
    dt_total = np.arange(1600) * DT_S
    rate = np.where(dt_total < 6.0, 0.4, 4.0)
    signal = np.cumsum(rate) * DT_S + np.random.default_rng(40).normal(0.0, SIGMA, 1600)
    starts = range(200, 1400 + 1, 50)
    windows = [signal[s - N:s] for s in starts]
    kinds = [lab.fault_type for lab in _labels(windows)]
    assert kinds[0] is FaultType.DRIFT and kinds[-1] is FaultType.RUNAWAY
    changes = [(a, b) for a, b in zip(kinds, kinds[1:], strict=False) if a is not b]
    assert changes == [(FaultType.DRIFT, FaultType.RUNAWAY)]


def test_a_runaway_at_its_limit_keeps_its_label() -> None:
    """-3 /s for 2 s, then held: once the ramp has left the window only a level is seen, which
    the ramp explains as well as a bias; the label stays runaway."""
    n_total = 1200
    tt = np.arange(n_total) * DT_S
    signal = -3.0 * np.minimum(np.maximum(tt - 1.5, 0.0), 2.0) + \
        np.random.default_rng(41).normal(0.0, SIGMA, n_total)
    windows = [signal[s - N:s] for s in range(200, n_total + 1, 50)]
    labels = _labels(windows[2:])  # raised 0.3 s after the onset
    assert {lab.fault_type for lab in labels} == {FaultType.RUNAWAY}
    assert labels[-1].magnitude == pytest.approx(-6.0, abs=5 * SIGMA)  # fitted end value


def test_no_data_is_taken_at_once() -> None:
    """An observation, not a shape: no hysteresis, confidence 1."""
    hyst = LabelHysteresis(P, WINS_N)
    r = _noise(50)
    r[150:] += 0.3
    assert hyst.decide(classify_residual(r, DT_S, P)).fault_type is FaultType.BIAS
    lab = hyst.update(Classification(FaultType.NO_DATA, float("nan"), confidence=1.0))
    assert lab.fault_type is FaultType.NO_DATA and lab.confidence == 1.0
