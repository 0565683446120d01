"""Preset-set campaigns (gcs_monitor.evaluation.campaign): one run end to end through the
MAVLink path (runs.run_one), its scores and the campaign report (report.write_report)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from gcs_monitor.config import MonitorConfig
from gcs_monitor.core.types import ChannelId
from gcs_monitor.core.units import DEG2RAD
from gcs_monitor.evaluation.campaign import run_campaign
from gcs_monitor.evaluation.records import (
    METHOD_MEDIAN,
    METHOD_MONITOR,
    CampaignResult,
    FaultTruth,
)
from gcs_monitor.evaluation.report import write_report
from gcs_monitor.evaluation.runs import run_one
from gcs_monitor.evaluation.scoring import air_fault_truth, tables_of
from gcs_monitor.fdi.events import AlarmKind, AlarmState
from sim_vehicle.faults.profiles import FaultSpec
from sim_vehicle.scenario import load_scenario, with_overrides

T_FAULT_S = 10.0
BIAS_DEG = 4.0


def _consensus_cfg() -> MonitorConfig:
    return MonitorConfig().with_family("imu", enabled=False).with_family("airdata",
                                                                         estimator="none")


def _short(faults: tuple[FaultSpec, ...], seed: int) -> object:
    sc = with_overrides(load_scenario("demo_airdata_faults"), duration_s=15.0, seed=seed)
    return dataclasses.replace(sc, faults=faults)


def test_single_bias_detected_fault_free_run_clean(tmp_path: Path) -> None:
    """A 4 deg AoA bias (4x J_th) on vane 1 at 10 s: detected within a second, isolated to
    aoa1; the same flight without the fault raises nothing (monitor and baselines)."""
    bias = FaultSpec("aoa1", "bias", T_FAULT_S, None, (("bias_rad", BIAS_DEG * DEG2RAD),))
    cfg = _consensus_cfg()
    faulty = run_one(0, _short((bias,), 3), cfg, keep_series=True)
    clean = run_one(1, _short((), 4), cfg)

    assert air_fault_truth(_short((bias,), 3)) == [
        FaultTruth(ChannelId("aoa", 1), "bias", 10_000_000, None)]
    raised = [e for e in faulty.events if e.state is AlarmState.RAISED
              and e.kind is AlarmKind.SENSOR_FAULT]
    assert [e.channel for e in raised] == [ChannelId("aoa", 1)]
    delay = (raised[0].t_us - 10_000_000) * 1e-6
    # n_D = 5 exceedances at 20 Hz air data: >= 4 samples after onset, well under 1 s
    assert 0.15 <= delay < 1.0
    o = faulty.outcomes[METHOD_MONITOR]["aoa"]
    assert o.faulty_run and not o.missed and not o.false_isolation
    assert o.delay_s == pytest.approx(delay)
    assert not faulty.outcomes[METHOD_MONITOR]["cas"].faulty_run
    # the baseline on the same samples sees the same 4 deg step
    assert faulty.outcomes[METHOD_MEDIAN]["aoa"].delay_s == pytest.approx(delay, abs=0.5)
    # residual against the consensus minus the applied bias is noise (0.1 deg sensor sigma)
    assert faulty.recon_rmse["aoa1"] < 0.3 * DEG2RAD

    for m, groups in clean.outcomes.items():
        for g, oc in groups.items():
            assert not oc.faulty_run and not oc.false_alarm, (m, g)
    assert clean.raised == {m: 0 for m in clean.raised}

    rows = {r.group: r for r in tables_of([faulty, clean])[METHOD_MONITOR]}
    assert rows["aoa"].n_faulty == 1 and rows["aoa"].n_fault_free == 1
    assert rows["aoa"].far_pct == 0.0 and rows["aoa"].mdr_pct == 0.0
    assert rows["aoa"].fir_pct == 0.0
    assert rows["aoa"].delay_max_s == pytest.approx(delay)
    assert rows["cas"].n_fault_free == 2 and rows["cas"].far_pct == 0.0
    assert faulty.series is not None and faulty.series["aoa.measured"].shape[1] == 3

    res = CampaignResult("hand", 2, 0, cfg, [faulty, clean], tables_of([faulty, clean]), "",
                         tmp_path, [], 0.0)
    md, files = write_report(res)
    assert {p.name for p in files} >= {"report.md", "metrics.csv", "runs.csv", "faults.csv",
                                       "example_series.csv", "residual_rms_example.png"}
    assert f"| {delay:.2f} |" in md  # the delay computed above reaches the table
    csv_rows = (tmp_path / "metrics.csv").read_text().splitlines()
    assert csv_rows[0].startswith("method,group") and len(csv_rows) == 1 + 2 + 2 + 2


@pytest.mark.slow
def test_quick_campaign_writes_report(tmp_path: Path) -> None:
    res = run_campaign("triplex", 6, 1, tmp_path, progress=False, config=_consensus_cfg())
    names = {p.name for p in res.files}
    assert {"report.md", "metrics.csv", "runs.csv", "faults.csv", "detection_delay.png",
            "rates_per_channel.png", "residual_rms_example.png"} <= names
    assert "Wan2018 Table IV" in res.markdown
    free = [r for r in res.runs if not r.faulty]
    assert free
    assert all(not o.false_alarm for r in free for o in r.outcomes[METHOD_MONITOR].values())
    assert res.row(METHOD_MONITOR, "aoa").far_pct == 0.0
