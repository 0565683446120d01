"""Wan2018 experiments (gcs_monitor.evaluation.papers.wan2018) and the slow-drift fix of the
MHE's fused measurement they measured (gcs_monitor.fdi.fusion.MheMeasurementFusion)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gcs_monitor.config import MonitorConfig
from gcs_monitor.core.types import ChannelId
from gcs_monitor.evaluation.configs import families_for
from gcs_monitor.evaluation.papers import wan2018
from gcs_monitor.families.airdata.estimator import AirDataEstimator
from gcs_monitor.fdi.events import AlarmKind, AlarmState, SetStatus
from gcs_monitor.fdi.fusion import MheMeasurementFusion
from gcs_monitor.monitor import Monitor
from sim_vehicle.run import iter_packets
from sim_vehicle.scenario import load_scenario


def _status(rms: tuple[float, ...], faulty: tuple[bool, ...] = (False, False, False)) -> SetStatus:
    return SetStatus(name="cas", t_us=0, measured=(0.0,) * 3, reference=0.0, fused=0.0,
                     weights=(0.0,) * 3, rms=rms, threshold=2.0, faulty=faulty,
                     configuration="fused 3/3")


def test_fusion_consensus_weight_breaks_the_model_following_loop() -> None:
    # Instance 0 drifts away from the other two while the model follows it (J_model of 0 small,
    # of 1 and 2 larger): eq. 19 on J_model alone would give 0 the largest weight.
    fus = MheMeasurementFusion(3, threshold=2.0, n_eval=10, floor_ratio=0.25)
    fused = None
    for _ in range(10):
        fused, w = fus.step([101.5, 100.0, 100.0], [True] * 3, _status((0.2, 1.4, 1.4)))
    # J_cons of 0 is 1.5 -> J_eff = (1.5, 1.4, 1.4): 0 gets less weight than each healthy one
    assert w[0] < w[1] and w[1] == pytest.approx(w[2])
    assert fused is not None and fused < 100.5


def test_fusion_equal_weights_below_floor_and_lost_set() -> None:
    fus = MheMeasurementFusion(3, threshold=2.0, n_eval=10, floor_ratio=0.25)
    fused, w = fus.step([1.0, 2.0, 3.0], [True] * 3, _status((0.1, 0.3, 0.4)))
    # consensus J of 0 and 2 after one sample: sqrt(1/10) = 0.32 < floor 0.5 -> equal weights
    assert w == pytest.approx((1 / 3, 1 / 3, 1 / 3))
    assert fused == pytest.approx(2.0)
    fused, w = fus.step([1.0, 2.0, 3.0], [True] * 3, _status((0.1, 0.3, 0.4), (True,) * 3))
    assert fused is None and not any(w)


def test_fusion_equal_pair_weights_for_the_last_two() -> None:
    # instance 0 isolated; 1 and 2 healthy with J 0.3 and 1.2 (J_th 2, floor 0.25 x 2 = 0.5)
    st = _status((5.0, 0.3, 1.2), (True, False, False))
    fused, w = MheMeasurementFusion(3, 2.0, 10, 0.25).step([9.0, 1.0, 2.0], [True] * 3, st)
    # eq. 19: 1/0.5^2 = 4 against 1/1.2^2 = 0.694
    assert w == pytest.approx((0.0, 4 / (4 + 1 / 1.44), (1 / 1.44) / (4 + 1 / 1.44)))
    fus = MheMeasurementFusion(3, 2.0, 10, 0.25, equal_pair=True)
    fused, w = fus.step([9.0, 1.0, 2.0], [True] * 3, st)
    assert w == pytest.approx((0.0, 0.5, 0.5)) and fused == pytest.approx(1.5)
    # one of the two above J_th leaves the fusion before it is confirmed (eq. 19's set S)
    fused, w = fus.step([9.0, 1.0, 7.0], [True] * 3, _status((5.0, 0.3, 2.5), (True, False, False)))
    assert w == pytest.approx((0.0, 1.0, 0.0)) and fused == pytest.approx(1.0)
    # three healthy: the rule does not apply (consensus J and the 0.25 J_th floor as before)
    fused, w = fus.step([1.0, 1.0, 1.0], [True] * 3, _status((0.3, 0.3, 1.2)))
    assert w[0] == pytest.approx(w[1]) and w[0] > 0.4 > w[2]


def test_experiments_registered() -> None:
    assert {"wan2018_fig45", "wan2018_fig3", "wan2018_campaign", "wan2018_campaign_literal_nrz",
            "wan2018_campaign_extensions", "wan2018_campaign_extensions_literal_nrz",
            "wan2018_calibration"} <= set(wan2018.experiments())


@pytest.mark.slow
def test_demo_preset_alarms_exactly_the_faulty_instances() -> None:
    """demo_airdata_faults (aoa1 bias, cas0 slow drift 0.5 kt/s, cas2 runaway -5 kt/s) through
    the MAVLink path with the CMHE reference (its defaults: fixed wind box, wings-level model)
    and no IMU estimator: exactly those three instances are raised."""
    sc = load_scenario("demo_airdata_faults")
    cfg = MonitorConfig().with_family("imu", enabled=False)
    mon = Monitor(cfg, families_for=families_for(cfg, airdata=AirDataEstimator))
    buf: list[bytes] = []
    for _, p in iter_packets(sc):
        buf.append(p)
        if len(buf) >= 64:
            mon.feed(b"".join(buf))
            buf.clear()
    mon.feed(b"".join(buf))
    mon.finish()
    raised = {e.channel for e in mon.events
              if e.state is AlarmState.RAISED and e.kind is AlarmKind.SENSOR_FAULT}
    assert raised == {ChannelId("aoa", 1), ChannelId("cas", 0), ChannelId("cas", 2)}


@pytest.mark.slow
def test_quick_campaign_metrics(tmp_path: Path) -> None:
    md = wan2018.wan2018_campaign(tmp_path, 1, True)
    assert "Table IV" in md and "Table III" in md and "By fault size against J_th" in md
    rows = (tmp_path / "wan2018_campaign_metrics.csv").read_text().splitlines()
    assert len(rows) == 1 + 4  # (monitor, median_vote) x (aoa, cas)
    for line in rows[1:]:
        method, group, n_free, n_faulty, far, *_ = line.split(",")
        assert int(n_free) + int(n_faulty) == 12
        if method == "monitor":
            assert float(far) == 0.0  # thresholds from fault-free calibration seeds
    assert (tmp_path / "wan2018_campaign_delays.png").stat().st_size > 0
    faults = (tmp_path / "wan2018_campaign_faults.csv").read_text().splitlines()
    head = faults[0].split(",")
    assert head[:6] == ["run", "name", "manoeuvre", "wind", "channel", "kind"]
    body = [dict(zip(head, f.split(","), strict=True)) for f in faults[1:]]
    assert body and all(b["monitor_detected"] in ("0", "1") for b in body)
    assert all(b["kind"] == "jam" or b["params_si"] for b in body)  # every other kind has params


def test_fault_size_by_hand() -> None:
    assert wan2018.fault_size("bias", "bias_rad=-0.05") == pytest.approx(0.05)
    assert wan2018.fault_size("oscillation", "amplitude_mps=10;frequency_hz=2") == \
        pytest.approx(10 / np.sqrt(2))
    assert wan2018.fault_size("noise", "sigma_rad=0.02") == pytest.approx(0.02)
    assert wan2018.fault_size("nrz", "level=0.1") is None
    assert wan2018.fault_size("jam", "") is None
    th = {"aoa": 0.02, "cas": 4.0}
    rows = [[0, "r", "level", "calm", "aoa0", "bias", 10.0, "bias_rad=0.05", "", 1, 0.2, 0, ""],
            [0, "r", "level", "calm", "aoa1", "bias", 10.0, "bias_rad=0.01", "", 0, "", 0, ""],
            # its own J_th (a turbulent run): 0.05 is then below J_th
            [2, "r", "level", "turbulence", "aoa2", "bias", 10.0, "bias_rad=0.05", 0.06, 1, 9.0,
             0, ""],
            [1, "r", "level", "calm", "cas2", "jam", 12.0, "", "", 1, 0.5, 1, 3.0]]
    out = {r[0]: r[1:] for r in wan2018.per_size_rows(rows, th)}
    assert out["size >= 2 J_th"][:2] == ["1 / 1", "0.20 / 0.20"]
    assert out["size < J_th"][:2] == ["1 / 2", "9.00 / 9.00"]
    assert out["jam"] == ["-", "-", "1 / 1", "0.50 / 0.50"]


def test_threshold_schedule_by_hand() -> None:
    # calm runs: worst J 0.3; turbulent: (1, 0.5) needs slope 0.2, (2, 0.6) 0.15 -> 0.2
    j0, s = wan2018.threshold_schedule([(0.0, 0.2), (0.0, 0.3), (1.0, 0.5), (2.0, 0.6)],
                                       min_runs=2)
    assert (j0, s) == pytest.approx((1.5 * 0.3, 1.5 * 0.2))
    # every calibration run lies under the line, one touches it
    pts = [(0.0, 0.2), (0.0, 0.3), (1.0, 0.5), (2.0, 0.6)]
    assert all(j <= (j0 + s * x) / 1.5 + 1e-12 for x, j in pts)
    # a turbulent run quieter than the calm ones never gives a negative slope
    assert wan2018.threshold_schedule([(0.0, 0.3), (2.0, 0.1)], min_runs=1) == \
        pytest.approx((0.45, 0.0))
    # too few calm (or turbulent) runs to trust a line: one fixed J_th, as Wan2018
    assert wan2018.threshold_schedule([(1.0, 0.5), (2.0, 0.6)], min_runs=1) == \
        pytest.approx((0.9, 0.0))
    assert wan2018.threshold_schedule(pts) == pytest.approx((0.9, 0.0))  # default min_runs 5
