"""Frozen-signal (jam) check of a redundant set: FrozenSignalCheck and its use in the monitor."""

from __future__ import annotations

import numpy as np
import pytest

from gcs_monitor.fdi.events import AlarmState, FaultType
from gcs_monitor.fdi.monitor import FrozenSignalCheck, RedundantSetMonitor, SetMonitorParams

SIGMA = 0.1  # sensor noise, SI
N = 40  # window, samples


def _feed(chk: FrozenSignalCheck, rows: np.ndarray) -> list[list[bool]]:
    out = []
    for row in rows:
        chk.update(row.tolist(), [True] * len(row))
        out.append(chk.frozen())
    return out


def test_mean_square_change_by_hand():
    chk = FrozenSignalCheck(2, 4, 0.01, 0.0)
    for a, b in [(0.0, 0.0), (1.0, 0.0), (3.0, 0.0), (2.0, 0.0), (2.0, 0.0)]:
        chk.update([a, b], [True, True])
    # changes of instance 0: 1, 2, -1, 0 -> mean square (1 + 4 + 1 + 0) / 4 = 1.5; instance 1: 0
    assert chk.activity() == pytest.approx([1.5, 0.0])
    # instance 1 never moved: no own past activity to collapse from, so it is not "frozen"
    assert chk.frozen() == [False, False]


def test_jam_is_frozen_after_one_window_and_healthy_peers_never():
    rng = np.random.default_rng(3)
    rows = 0.05 + SIGMA * rng.standard_normal((400, 3))
    rows[150:, 1] = rows[150, 1]  # instance 1 jammed at sample 150
    flags = np.array(_feed(FrozenSignalCheck(3, N, 0.01, (0.01 * SIGMA) ** 2), rows))
    assert not flags[:, [0, 2]].any()
    first = int(np.argmax(flags[:, 1]))
    # frozen once the window holds (almost) only the zero changes of the jam
    assert 150 + N // 2 < first <= 150 + N
    # frozen for as long as its own older windows remember it moving (the monitor latches)
    assert flags[first:first + 3 * N, 1].all()


def test_double_jam_is_found_while_one_instance_moves():
    rng = np.random.default_rng(8)
    rows = 0.05 + SIGMA * rng.standard_normal((400, 3))
    rows[150:, 0] = rows[150, 0]
    rows[170:, 2] = rows[170, 2]
    flags = np.array(_feed(FrozenSignalCheck(3, N, 0.01, (0.01 * SIGMA) ** 2), rows))
    assert not flags[:, 1].any()
    assert 150 < int(np.argmax(flags[:, 0])) <= 150 + N
    assert 170 < int(np.argmax(flags[:, 2])) <= 170 + N


def test_unequal_noise_and_a_constant_set_are_not_frozen():
    rng = np.random.default_rng(4)
    rows = SIGMA * rng.standard_normal((2000, 3)) * np.array([1.0, 3.0, 1.5])  # noise 3x apart
    assert not np.array(_feed(FrozenSignalCheck(3, N, 0.01, 1e-8), rows)).any()
    const = np.full((200, 3), 1.25)  # parked: every instance constant
    assert not np.array(_feed(FrozenSignalCheck(3, N, 0.01, 1e-8), const)).any()


def test_a_noisy_faulty_instance_does_not_make_healthy_ones_frozen():
    rng = np.random.default_rng(7)
    rows = 0.05 + SIGMA * rng.standard_normal((600, 3))
    rows[:, 0] += 50 * SIGMA * rng.standard_normal(600)  # noise fault, 50x the sensor noise
    rows[300:, 2] = rows[300, 2]  # and a jam on instance 2
    flags = np.array(_feed(FrozenSignalCheck(3, N, 0.01, (0.01 * SIGMA) ** 2), rows))
    assert not flags[:, :2].any()
    assert flags[300 + N:300 + 3 * N, 2].all()


def test_invalid_samples_restart_the_window():
    chk = FrozenSignalCheck(2, 4, 0.01, 0.0)
    rng = np.random.default_rng(5)
    for k in range(10):
        chk.update([1.0, float(rng.standard_normal())], [k != 6, True])
    # the gap at k = 6 restarted instance 0's windows: 2 changes since, no past windows
    assert chk.activity()[0] != chk.activity()[0] and chk._past[0] == []
    assert chk.frozen() == [False, False]


def test_monitor_raises_stuck_for_a_jam_the_residual_cannot_see():
    """Steady flight: the jammed vane equals the truth at jam time, so its model residual stays
    at noise level (eq. 17 never crosses J_th); the frozen-signal check isolates it."""
    p = SetMonitorParams(threshold=4 * SIGMA, noise_sigma=SIGMA, runaway_rate_per_s=1.0,
                         dt_s=0.05, stuck_n=N)
    mon = RedundantSetMonitor("aoa", 3, p, estimator="test")
    rng = np.random.default_rng(6)
    truth = 0.05
    events = []
    for k in range(600):
        m = truth + SIGMA * rng.standard_normal(3)
        if k >= 200:
            m[2] = truth
        _, ev = mon.step(k * 50_000, m, [True, True, True], reference=truth)
        events += ev
    raised = [e for e in events if e.state is AlarmState.RAISED]
    assert [(e.channel.instance, e.fault_type) for e in raised] == [(2, FaultType.STUCK)]
    assert 200 * 50_000 < raised[0].t_us <= (200 + N) * 50_000
    assert mon.faulty == (False, False, True)


def test_monitor_without_the_check_misses_that_jam():
    p = SetMonitorParams(threshold=4 * SIGMA, noise_sigma=SIGMA, runaway_rate_per_s=1.0,
                         dt_s=0.05, stuck_n=0)
    mon = RedundantSetMonitor("aoa", 3, p, estimator="test")
    rng = np.random.default_rng(6)
    for k in range(600):
        m = 0.05 + SIGMA * rng.standard_normal(3)
        if k >= 200:
            m[2] = 0.05
        mon.step(k * 50_000, m, [True, True, True], reference=0.05)
    assert mon.faulty == (False, False, False)
