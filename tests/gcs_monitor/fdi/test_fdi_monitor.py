"""RedundantSetMonitor / ChannelMonitor on synthetic triplex scenarios, vs the median baseline.

Triplex AoA at 100 Hz, sensor noise SIGMA rad, J_th = 4 SIGMA, faults from t = 2 s.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_monitor.core.types import ChannelId
from gcs_monitor.fdi.baselines import MedianVoteMonitor, MedianVoteParams, fixed_threshold_monitor
from gcs_monitor.fdi.confirmation import ConfirmationParams
from gcs_monitor.fdi.events import (
    SET_INSTANCE,
    AlarmEvent,
    AlarmKind,
    AlarmState,
    ChannelStatus,
    FaultType,
)
from gcs_monitor.fdi.monitor import (
    ChannelMonitor,
    ChannelMonitorParams,
    RedundantSetMonitor,
    SetMonitorParams,
    calibrate,
)

DT_US = 10_000
SIGMA = 0.002  # rad, vane noise 1-sigma
TH = 4 * SIGMA
T_FAULT_US = 2_000_000
PARAMS = SetMonitorParams(threshold=TH, noise_sigma=SIGMA, runaway_rate_per_s=0.02)


def _truth(k: np.ndarray) -> np.ndarray:
    t = k * DT_US * 1e-6
    return 0.05 + 0.03 * np.sin(2 * np.pi * 0.2 * t)  # manoeuvring AoA, rad


def _scenario(n_steps: int, faults: dict[int, np.ndarray], seed: int) -> np.ndarray:
    """(n_steps, 3) measurements: truth + noise + additive faults per instance."""
    k = np.arange(n_steps)
    rng = np.random.default_rng(seed)
    y = _truth(k)[:, None] + rng.normal(0.0, SIGMA, (n_steps, 3))
    for i, f in faults.items():
        y[:, i] += f
    return y


def _ramp(n_steps: int, rate_per_s: float, start_us: int = T_FAULT_US) -> np.ndarray:
    t_s = (np.arange(n_steps) * DT_US - start_us) * 1e-6
    return np.where(t_s > 0, rate_per_s * t_s, 0.0)


def _step(n_steps: int, value: float) -> np.ndarray:
    return np.where(np.arange(n_steps) * DT_US >= T_FAULT_US, value, 0.0)


def _run(mon: object, y: np.ndarray, ref: np.ndarray | None = None):  # type: ignore[no-untyped-def]
    valid = np.ones(3, dtype=bool)
    events: list[AlarmEvent] = []
    statuses = []
    for k in range(y.shape[0]):
        st, ev = mon.step(k * DT_US, y[k], valid, None if ref is None else float(ref[k]))  # type: ignore[attr-defined]
        events += ev
        statuses.append(st)
    return statuses, events


def _raised(events: list[AlarmEvent], kind: AlarmKind = AlarmKind.SENSOR_FAULT) -> dict[int, int]:
    out: dict[int, int] = {}
    for e in events:
        if e.state is AlarmState.RAISED and e.kind is kind:
            out.setdefault(e.channel.instance, e.t_us)
    return out


def _reference(n: int, seed: int) -> np.ndarray:
    """A model prediction: truth + smaller independent error (stands in for Wan2018's MHE)."""
    return _truth(np.arange(n)) + np.random.default_rng(seed).normal(0.0, 0.5 * SIGMA, n)


def test_single_bias_isolated_and_classified() -> None:
    n = 400
    y = _scenario(n, {1: _step(n, 20 * SIGMA)}, seed=1)
    st, ev = _run(RedundantSetMonitor("aoa", 3, PARAMS), y)
    raised = _raised(ev)
    assert set(raised) == {1}
    # J of a 20-sigma step crosses 4 sigma after 1 sample; n_D = 5 confirms after 5
    assert raised[1] - T_FAULT_US <= 5 * DT_US
    first = next(e for e in ev if e.state is AlarmState.RAISED)
    assert first.fault_type is FaultType.BIAS
    assert first.magnitude == pytest.approx(20 * SIGMA, abs=3 * SIGMA)
    assert first.channel == ChannelId("aoa", 1)
    after = [s for s in st if s.t_us > raised[1]]
    assert all(s.weights[1] == 0.0 and s.faulty == (False, True, False) for s in after)
    err = np.array([s.fused for s in after]) - _truth(np.arange(n))[-len(after):]
    assert np.max(np.abs(err)) < 4 * SIGMA
    assert after[-1].configuration == "fused 2/3"


def test_single_drift_loses_weight_before_detection() -> None:
    n = 600
    y = _scenario(n, {0: _ramp(n, 0.01)}, seed=2)  # 0.01 rad/s: crosses 4 sigma after 0.8 s
    st, ev = _run(RedundantSetMonitor("aoa", 3, PARAMS), y)
    raised = _raised(ev)
    assert set(raised) == {0}
    # eq. 19: just before the declaration the drifting instance already has the least weight
    before = next(s for s in st if s.t_us == raised[0] - DT_US)
    assert before.weights[0] < min(before.weights[1], before.weights[2])
    assert before.weights[0] < 0.5 / 3
    kinds = {e.fault_type for e in ev if e.channel.instance == 0}
    assert FaultType.DRIFT in kinds or FaultType.RUNAWAY in kinds


def test_double_opposite_faults_isolated_without_reference() -> None:
    n = 400
    # both confirmed while all three are still in the median set
    y = _scenario(n, {0: _step(n, 15 * SIGMA), 2: _step(n, -20 * SIGMA)}, seed=3)
    st, ev = _run(RedundantSetMonitor("aoa", 3, PARAMS), y)
    assert set(_raised(ev)) == {0, 2}  # the median stays on the good instance 1
    assert st[-1].faulty == (True, False, True)
    assert abs(st[-1].fused - _truth(np.array([n - 1]))[0]) < 4 * SIGMA


def test_double_same_side_drift_with_reference_vs_baseline() -> None:
    n = 800
    faults = {0: _ramp(n, 0.02), 1: _ramp(n, 0.02)}
    y = _scenario(n, faults, seed=4)
    ref = _reference(n, seed=40)
    st, ev = _run(RedundantSetMonitor("aoa", 3, PARAMS, estimator="airdata_cmhe"), y, ref)
    assert set(_raised(ev)) == {0, 1}
    assert st[-1].faulty == (True, True, False)
    assert abs(st[-1].fused - y[-1, 2]) < 1e-15  # only the good instance remains
    # the majority-vote baseline isolates the GOOD instance: the median follows the pair
    bst, bev = _run(MedianVoteMonitor("aoa", 3, MedianVoteParams(threshold=TH)), y)
    assert set(_raised(bev)) == {2}
    assert abs(bst[-1].fused - _truth(np.array([n - 1]))[0]) > 0.05  # outputs the faulty pair


def test_double_same_side_drift_without_reference_is_not_isolable() -> None:
    """Honest limit (isolation.py): f1 = f2 on two of three looks like -f on the third."""
    n = 800
    y = _scenario(n, {0: _ramp(n, 0.02), 1: _ramp(n, 0.02)}, seed=4)
    _, ev = _run(RedundantSetMonitor("aoa", 3, PARAMS), y)
    assert set(_raised(ev)) == {2}  # same false isolation as majority voting


def test_staggered_same_side_drift_without_reference_gives_set_lost() -> None:
    """First fault isolated; second one leaves two disagreeing instances: both rejected
    (SET_LOST, no value), where the non-latching fixed-threshold voter keeps the faulty one."""
    n = 1200
    y = _scenario(n, {0: _ramp(n, 0.05), 1: _ramp(n, 0.02, start_us=5_000_000)}, seed=5)
    st, ev = _run(RedundantSetMonitor("aoa", 3, PARAMS), y)
    raised = _raised(ev)
    assert set(raised) == {0, 1, 2} and raised[0] < raised[1] == raised[2]
    assert _raised(ev, AlarmKind.SET_LOST) == {SET_INSTANCE: raised[1]}
    assert math.isnan(st[-1].fused) and st[-1].configuration == "lost: none"
    bst, _ = _run(fixed_threshold_monitor("aoa", 3, TH), y)
    assert bst[-1].faulty[2] and not bst[-1].faulty[1]  # good one out, drifting one in


def test_triple_fault_set_lost_virtual_sensor() -> None:
    n = 400
    y = _scenario(n, {0: _step(n, 10 * SIGMA), 1: _ramp(n, 0.03), 2: _step(n, -12 * SIGMA)},
                  seed=6)
    ref = _reference(n, seed=60)
    st, ev = _run(RedundantSetMonitor("aoa", 3, PARAMS, estimator="airdata_cmhe"), y, ref)
    assert set(_raised(ev)) == {0, 1, 2}
    lost = _raised(ev, AlarmKind.SET_LOST)
    assert set(lost) == {SET_INSTANCE}
    after = [s for s in st if s.t_us >= lost[SET_INSTANCE]]
    assert all(s.fused == s.reference for s in after)  # Table I: model estimate replaces the set
    assert after[-1].configuration == "lost: virtual"


@pytest.mark.parametrize("use_ref", [False, True])
def test_noise_only_no_alarm_100k(use_ref: bool) -> None:
    n = 100_000
    y = _scenario(n, {}, seed=7)
    ref = _reference(n, seed=70) if use_ref else None
    st, ev = _run(RedundantSetMonitor("aoa", 3, PARAMS), y, ref)
    assert ev == []
    assert max(max(s.rms) for s in st) < TH


def test_deterministic_replay() -> None:
    n = 600
    y = _scenario(n, {0: _ramp(n, 0.02), 2: _step(n, 8 * SIGMA)}, seed=8)
    a = _run(RedundantSetMonitor("aoa", 3, PARAMS), y)
    b = _run(RedundantSetMonitor("aoa", 3, PARAMS), y)
    assert a[1] == b[1] and len(a[1]) > 0
    assert [s.fused for s in a[0]] == [s.fused for s in b[0]]


def test_invalid_instance_is_not_a_fault() -> None:
    n = 300
    y = _scenario(n, {}, seed=9)
    mon = RedundantSetMonitor("aoa", 3, PARAMS)
    valid = np.array([True, False, True])
    for k in range(n):
        y[k, 1] = math.nan
        st, ev = mon.step(k * DT_US, y[k], valid, None)
        assert ev == []
    assert st.weights[1] == 0.0 and st.configuration == "fused 2/3"


def test_channel_monitor_and_calibrate() -> None:
    rng = np.random.default_rng(10)
    free = rng.normal(0.0, 0.05, 5000)  # fault-free reconstructed accelerometer fault, m/s^2
    th = calibrate(free, rms_window_n=10, rule="max", k=1.5)
    c = np.sqrt(np.convolve(free**2, np.ones(10), "valid") / 10)
    assert th == pytest.approx(1.5 * c.max(), rel=1e-12)
    assert calibrate(free, rule="mean_std", k=6) == pytest.approx(c.mean() + 6 * c.std(), rel=1e-9)
    ch = ChannelId("acc", 0, "x")
    mon = ChannelMonitor(ch, ChannelMonitorParams(threshold=th, noise_sigma=0.05,
                                                  runaway_rate_per_s=1.0), estimator="imu_ts")
    events: list[AlarmEvent] = []
    vals = np.concatenate([rng.normal(0, 0.05, 500), 1.0 + rng.normal(0, 0.05, 500),
                           rng.normal(0, 0.05, 1000)])
    for k, v in enumerate(vals):
        st, ev = mon.step(k * DT_US, float(v), True)
        events += ev
    states = [e.state for e in events]
    assert states[0] is AlarmState.RAISED and states[-1] is AlarmState.CLEARED
    assert events[0].fault_type is FaultType.BIAS
    assert events[0].magnitude == pytest.approx(1.0, abs=0.1)
    assert 500 * DT_US <= events[0].t_us <= 506 * DT_US
    assert not st.faulty


def test_channel_id_hash_is_cached_and_survives_pickling() -> None:
    """ChannelId caches its hash; pickling rebuilds it, since string hashes are per process."""
    import pickle

    ch = ChannelId("acc", 0, "x")
    assert hash(ch) == hash(("acc", 0, "x")) and ch == ChannelId("acc", 0, "x")
    back = pickle.loads(pickle.dumps({ch: 1}))
    assert back[ChannelId("acc", 0, "x")] == 1
    assert ChannelId("acc", 0, "x") < ChannelId("acc", 0, "y")


def test_channel_monitor_update_equals_step() -> None:
    """update() is step() without the ChannelStatus: same alarm events, same state."""
    ch = ChannelId("acc", 0, "x")
    p = ChannelMonitorParams(threshold=0.3, noise_sigma=0.05, runaway_rate_per_s=1.0)
    a = ChannelMonitor(ch, p, estimator="imu_ts")
    b = ChannelMonitor(ch, p, estimator="imu_ts")
    rng = np.random.default_rng(3)
    x = rng.normal(size=2000) * 0.05
    x[500:900] += 1.0
    for k, v in enumerate(x):
        st, ev_a = a.step(k * 10_000, float(v), k % 97 != 0)
        ev_b = b.update(k * 10_000, float(v), k % 97 != 0)
        assert ev_a == ev_b and st.rms == b._J and st.faulty == b._faulty


@pytest.mark.parametrize("latch", [False, True])
def test_channel_bank_equals_channel_monitors(latch: bool) -> None:
    """ChannelBank (one numba call per sample for all channels) against one ChannelMonitor per
    channel: identical J, decisions, events and statuses over 3000 samples (past the exact
    re-summation at 1000 and 2000), with raises, clears, invalid and NaN samples."""
    from gcs_monitor.fdi.monitor import ChannelBank

    chans = [ChannelId("acc", 0, a) for a in "xyz"] + [ChannelId("gyro", 0, "p")]
    conf = ConfirmationParams(latch=latch)
    params = [ChannelMonitorParams(threshold=th, noise_sigma=0.05, runaway_rate_per_s=1.0,
                                   confirmation=conf) for th in (0.3, 0.3, 0.5, 0.01)]
    ref = [ChannelMonitor(c, p, estimator="imu_ts") for c, p in zip(chans, params, strict=False)]
    bank = ChannelBank.create([ChannelMonitor(c, p, estimator="imu_ts")
                               for c, p in zip(chans, params, strict=False)])
    assert bank is not None
    rng = np.random.default_rng(7)
    x = rng.normal(size=(3000, 4)) * [0.05, 0.05, 0.05, 0.002]
    x[400:900, 0] += 1.0  # bias: raise, updates, clear (if not latched)
    x[1500:2600, 1] += np.linspace(0.0, 2.0, 1100)  # drift
    x[2000:2100, 3] += 0.05 * np.sin(np.arange(100))  # oscillation on a tight threshold
    x[1234, 2] = np.nan
    for k in range(3000):
        valid = k % 113 != 5
        t_us = k * 10_000
        ev_ref, st_ref = [], []
        for m, v in zip(ref, x[k].tolist(), strict=True):
            st, ev = m.step(t_us, v, valid)
            ev_ref += ev
            st_ref.append(st)
        st_bank: list[ChannelStatus] = []
        ev_bank = bank.update(t_us, x[k].tolist(), valid, st_bank)
        assert ev_bank == ev_ref, k
        for a, b in zip(st_ref, st_bank, strict=True):
            assert (a.rms, a.faulty, a.threshold, a.channel) == (b.rms, b.faulty, b.threshold,
                                                                 b.channel), k
            assert a.value == b.value or (a.value != a.value and b.value != b.value)


def _restart_case(peer_residual_after: float, restart: bool) -> tuple[list[bool], list[bool]]:
    """Reference-based set, J_th = 1, N_eval = 10, n_D = 5. Instance 1 carries a residual of 5
    from k = 0 (J = 1.58 at once: confirmed at k = 4). Instance 0 carries 2.0 for k = 0..4 (the
    pull of instance 1 on the reference) and ``peer_residual_after`` from k = 5 on."""
    p = SetMonitorParams(threshold=1.0, noise_sigma=0.01, runaway_rate_per_s=0.02,
                         restart_peers=restart)
    mon = RedundantSetMonitor("aoa", 3, p, estimator="airdata_cmhe")
    f0, f1 = [], []
    for k in range(30):
        r0 = 2.0 if k < 5 else peer_residual_after
        st, _ = mon.step(k * DT_US, [r0, 5.0, 0.0], [True, True, True], 0.0)
        f0.append(st.faulty[0])
        f1.append(st.faulty[1])
    return f0, f1


def test_restart_peers_drops_residuals_taken_against_the_faulty_peer() -> None:
    """Hand count: instance 0's J crosses 1 at k = 2 (sqrt(3 * 4 / 10) = 1.10). Without the
    restart its window keeps the five 2.0s until k = 14, so it collects its 5th exceedance at
    k = 6 and is falsely isolated; with the restart at k = 4 its window holds only zeros after."""
    f0, f1 = _restart_case(0.0, restart=False)
    assert f1.index(True) == 4 and f0.index(True) == 6
    f0, f1 = _restart_case(0.0, restart=True)
    assert f1.index(True) == 4 and not any(f0)


def test_restart_peers_still_isolates_a_peer_that_is_faulty_too() -> None:
    """A peer whose residual stays at 2.0 is confirmed from fresh residuals: the window
    restarts empty at k = 4, J = sqrt(3 * 4 / 10) > 1 from k = 7, 5th exceedance at k = 11
    (against k = 6 without the restart)."""
    f0, _ = _restart_case(2.0, restart=False)
    assert f0.index(True) == 6
    f0, _ = _restart_case(2.0, restart=True)
    assert f0.index(True) == 11
