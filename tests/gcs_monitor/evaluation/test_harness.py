"""Evaluation harness: scoring against hand-checkable truth, preset sets, end to end runs."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import pytest

from gcs_monitor.config import MonitorConfig
from gcs_monitor.core.types import ChannelId
from gcs_monitor.core.units import DEG2RAD
from gcs_monitor.evaluation.harness import (
    METHOD_MEDIAN,
    METHOD_MONITOR,
    CampaignResult,
    FaultTruth,
    channel_of,
    fault_truth,
    run_campaign,
    run_one,
    score_faults,
    tables_of,
)
from gcs_monitor.evaluation.report import write_report
from gcs_monitor.fdi.events import AlarmEvent, AlarmKind, AlarmState, FaultType
from sim_vehicle.campaigns import PRESET_SETS, TRIPLEX_KINDS, generate_set, list_preset_sets
from sim_vehicle.faults.profiles import FaultSpec
from sim_vehicle.scenario import load_scenario, with_overrides

T_FAULT_S = 10.0
BIAS_DEG = 4.0


def _ev(t_s: float, ch: ChannelId, state: AlarmState = AlarmState.RAISED,
        kind: AlarmKind = AlarmKind.SENSOR_FAULT) -> AlarmEvent:
    return AlarmEvent(round(t_s * 1e6), ch, state, kind, FaultType.BIAS, 0.0, 0.0, 1.0, "test")


def test_channel_names_map_to_air_data_channels() -> None:
    assert channel_of("aoa2") == ChannelId("aoa", 2)
    assert channel_of("cas0") == ChannelId("cas", 0)
    assert channel_of("imu0.acc.x") is None  # not an air-data set: not scored by the harness
    assert channel_of("ssa") is None


def test_score_faults_by_hand() -> None:
    aoa1 = ChannelId("aoa", 1)
    faults = [FaultTruth(aoa1, "bias", 10_000_000, None),
              FaultTruth(ChannelId("cas", 2), "drift", 20_000_000, None)]
    events = [_ev(9.0, aoa1),  # before the fault: not a detection of it
              _ev(10.5, aoa1),  # detection, 0.5 s delay
              _ev(11.0, aoa1, AlarmState.UPDATED),
              _ev(21.0, ChannelId("cas", 2), kind=AlarmKind.LINK),  # link alarms never count
              _ev(22.0, ChannelId("cas", -1), kind=AlarmKind.SET_LOST)]
    res = score_faults("m", events, faults)
    assert res[0].detected and res[0].delay_s == pytest.approx(0.5)
    assert not res[1].detected and math.isnan(res[1].delay_s)


def test_preset_sets_are_deterministic_and_cover_the_issue() -> None:
    assert {n for n, _ in list_preset_sets()} == set(PRESET_SETS) >= {"triplex", "wan2018",
                                                                     "fault_free"}
    a = generate_set("triplex", 24, seed=5)
    assert a == generate_set("triplex", 24, seed=5)
    assert generate_set("triplex", 6, seed=5) == a[:6]  # a prefix keeps the mix
    assert a != generate_set("triplex", 24, seed=6)
    kinds = {f.kind for sc in a for f in sc.faults}
    assert kinds == set(TRIPLEX_KINDS)
    n_faults = [len(sc.faults) for sc in a]
    assert 0 in n_faults and 1 in n_faults and 2 in n_faults
    for sc in a:
        assert sc.airframe == "transport" and 60.0 <= sc.duration_s <= 120.0
        for f in sc.faults:
            assert channel_of(f.channel) is not None
            assert 15.0 <= f.t_start_s < sc.duration_s
    free = generate_set("fault_free", 7)
    assert all(not sc.faults for sc in free)
    assert len({sc.manoeuvre.kind for sc in free}) == 7  # every manoeuvre kind
    with pytest.raises(ValueError, match="unknown preset set"):
        generate_set("nope", 1)


def _consensus_cfg() -> MonitorConfig:
    c = MonitorConfig()
    return dataclasses.replace(c, estimators=dataclasses.replace(
        c.estimators, imu_ts=False, imu_hosm=False, airdata="none"))


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

    assert fault_truth(_short((bias,), 3)) == [
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


def test_declared_weather_is_the_scenario_forecast_rounded_up() -> None:
    """The monitor receives the scenario's wind *specification* coarsened like a forecast:
    speed 5 kt steps, vertical 1 kt, shear 5 kt, sigma 1 kt; shear rate pi A / T (A/2 (1 - cos))."""
    from gcs_monitor.core.units import KT2MPS
    from gcs_monitor.evaluation.harness import declared_weather
    from sim_vehicle.environment.wind import SHEAR_DURATION_S
    from sim_vehicle.scenario import WindSpec

    sc = generate_set("triplex", 1, 0)[0]
    w = WindSpec(kind="shear+turbulence", mean_ned_mps=(3.0, 4.0, -0.6),
                 turbulence_sigma_mps=2.51, shear_amplitude_mps=10.0)
    a = declared_weather(dataclasses.replace(sc, wind=w))
    assert a.wind_mps == pytest.approx(10.0 * KT2MPS)  # 5 m/s = 9.7 kt -> 10 kt
    assert a.wind_z_mps == pytest.approx(2.0 * KT2MPS)  # 0.6 m/s = 1.2 kt -> 2 kt
    assert a.turbulence_sigma_mps == pytest.approx(5.0 * KT2MPS)  # 4.88 kt -> 5 kt
    assert a.shear_mps == pytest.approx(20.0 * KT2MPS)  # 19.4 kt -> 20 kt
    assert a.shear_rate_mps2 == pytest.approx(math.pi * 20.0 * KT2MPS / SHEAR_DURATION_S)
    calm = declared_weather(dataclasses.replace(sc, wind=dataclasses.replace(w, kind="calm")))
    assert calm.wind_mps == calm.shear_mps == calm.turbulence_sigma_mps == 0.0


def test_evaluate_list_describes_every_experiment(capsys: pytest.CaptureFixture[str]) -> None:
    from gcs_monitor.cli import main
    from gcs_monitor.evaluation import registry

    assert main(["evaluate", "--list"]) == 0
    lines = capsys.readouterr().out.splitlines()
    names = sorted(registry.experiments())
    assert [ln.split()[0] for ln in lines] == names
    assert all(len(ln.split(maxsplit=1)) == 2 for ln in lines)  # each has a description
    assert main(["evaluate", "--experiment", "no_such_experiment"]) == 2
    assert "unknown experiment 'no_such_experiment'" in capsys.readouterr().err


def test_registry_summary_is_one_line() -> None:
    from gcs_monitor.evaluation.registry import summary

    def exp(out: object, jobs: int, quick: bool) -> str:
        """Uses :func:`thing` and ``code``, over
        two lines.

        Second paragraph, not shown."""
        return ""

    assert summary(exp) == "Uses thing and `code`, over two lines."  # type: ignore[arg-type]
    assert summary(exp, width=20).endswith(" ...") and len(summary(exp, width=20)) <= 24  # type: ignore[arg-type]
