"""The replay fast paths change no result.

One simulated flight with the Lu2016 Table 2 IMU faults goes through the Monitor with both IMU
estimators three ways: the default fast path without consumers of per-channel statuses (no
sinks, no on_step: ChannelMonitor.update, packed ATSEKF kernel), the same with an on_step
callback (ChannelMonitor.step builds every ChannelStatus), and with imu_ts forced through the
plain ``two_stage_step`` (no packed kernel). Alarm events must be identical, and the Estimates of
the two estimator paths equal (bitwise: the packed kernel makes the same operations).
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Any

import numpy as np
import pytest

from gcs_monitor.config import MonitorConfig
from gcs_monitor.families.base import FamilyContext
from gcs_monitor.families.imu.family import ImuFamily
from gcs_monitor.monitor import Monitor
from gcs_monitor.pipeline import build_families

DURATION_S = 32.0  # Table 2 faults at 10-30 s; IMU channels judged after a 5 s warm-up


@functools.cache
def _flight() -> bytes:
    from sim_vehicle.run import iter_packets
    from sim_vehicle.scenario import load_scenario

    sc = dataclasses.replace(load_scenario("lu2016_calm"), duration_s=DURATION_S)
    return b"".join(p for _, p in iter_packets(sc))


def _replay(*, plain_imu_ts: bool, on_step: bool) -> tuple[list[Any], list[Any]]:
    imu = MonitorConfig().family("imu")
    imu = dataclasses.replace(imu, hosm=dataclasses.replace(imu.hosm, enabled=True))
    cfg = MonitorConfig().with_family("imu", imu).with_family("airdata", estimator="none")
    estimates: list[Any] = []

    def families_for(ctx: FamilyContext) -> list[Any]:
        fams = build_families(dict(cfg.families), ctx)
        if plain_imu_ts:
            for fam in fams:
                if isinstance(fam, ImuFamily):
                    for est in fam.estimators:
                        if est.name == "imu_ts":
                            # every step through filters.two_stage.two_stage_step
                            est._packed = None  # type: ignore[attr-defined]
        return fams

    def record(sysid: int, frame: Any, step: Any) -> None:
        estimates.extend(step.estimates)

    mon = Monitor(cfg, families_for=families_for, on_step=record if on_step else None)
    data = _flight()
    for i in range(0, len(data), 4096):
        mon.feed(data[i:i + 4096])
    mon.finish()
    return list(mon.events), estimates


def test_fast_paths_give_the_same_alarms_and_estimates() -> None:
    fast_events, _ = _replay(plain_imu_ts=False, on_step=False)
    step_events, fast_est = _replay(plain_imu_ts=False, on_step=True)
    plain_events, plain_est = _replay(plain_imu_ts=True, on_step=True)
    assert any(e.estimator == "imu_ts" for e in fast_events)  # the faults are alarmed
    assert fast_events == step_events == plain_events
    assert len(fast_est) == len(plain_est) > 0
    for a, b in zip(fast_est, plain_est, strict=True):
        assert (a.name, a.t_us, a.available, a.numerics_ok) == (b.name, b.t_us, b.available,
                                                                 b.numerics_ok)
        assert a.faults == b.faults and a.residuals == b.residuals and a.virtual == b.virtual
        for k in a.states:
            np.testing.assert_array_equal(a.states[k], b.states[k])


if __name__ == "__main__":  # pragma: no cover
    pytest.main([__file__, "-q"])
