"""No-data check of a redundant set: an instance that stops delivering valid values while a peer
still does is isolated (fault type ``no_data``); a whole set going quiet is a link matter."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_monitor.fdi.confirmation import ConfirmationParams
from gcs_monitor.fdi.events import AlarmState, FaultType
from gcs_monitor.fdi.monitor import RedundantSetMonitor, SetMonitorParams

SIGMA = 0.1
DT_US = 50_000


def _monitor(no_data_n: int, latch: bool = True) -> RedundantSetMonitor:
    p = SetMonitorParams(threshold=4 * SIGMA, noise_sigma=SIGMA, runaway_rate_per_s=1.0,
                         dt_s=0.05, no_data_n=no_data_n,
                         confirmation=ConfirmationParams(latch=latch))
    return RedundantSetMonitor("cas", 3, p, estimator="test")


def _run(mon: RedundantSetMonitor, valid_fn, n: int = 300):
    rng = np.random.default_rng(2)
    events = []
    for k in range(n):
        m = 80.0 + SIGMA * rng.standard_normal(3)
        v = valid_fn(k)
        m = [x if ok else math.nan for x, ok in zip(m, v, strict=True)]
        _, ev = mon.step(k * DT_US, m, v, reference=80.0)
        events += ev
    return events


def test_silent_instance_is_isolated_after_the_window():
    mon = _monitor(10)
    events = _run(mon, lambda k: [True, k < 100, True])
    raised = [e for e in events if e.state is AlarmState.RAISED]
    assert [(e.channel.instance, e.fault_type) for e in raised] == [(1, FaultType.NO_DATA)]
    # the 10th sample without a value (k = 109) raises it
    assert raised[0].t_us == 109 * DT_US
    assert math.isnan(raised[0].magnitude)
    assert mon.faulty == (False, True, False)


def test_whole_set_quiet_and_never_seen_instances_raise_nothing():
    mon = _monitor(10)
    # all three drop out together (a link gap), then come back
    events = _run(mon, lambda k: [not 100 <= k < 200] * 3)
    # instance 2 is never delivered at all (a duplex installation in a triplex message set)
    mon2 = _monitor(10)
    events += _run(mon2, lambda k: [True, True, False])
    assert [e for e in events if e.state is AlarmState.RAISED] == []
    assert mon.faulty == mon2.faulty == (False, False, False)


def test_short_gap_is_tolerated_and_off_means_off():
    mon = _monitor(10)
    assert _run(mon, lambda k: [True, not 100 <= k < 109, True]) == []  # 9 samples: fine
    off = _monitor(0)
    assert _run(off, lambda k: [True, k < 100, True]) == []


@pytest.mark.parametrize(("latch", "faulty_after"), [(True, True), (False, False)])
def test_return_of_the_instance_follows_the_latch(latch, faulty_after):
    mon = _monitor(10, latch=latch)  # unlatched: clears after clear_n (50) quiet samples
    _run(mon, lambda k: [True, not 100 <= k < 150, True], n=400)
    assert mon.faulty[1] is faulty_after
