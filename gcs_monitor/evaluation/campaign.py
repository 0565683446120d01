"""Preset-set campaigns (``gcs-monitor evaluate --preset-set``): simulate, monitor, score, report.

Each run is :func:`~gcs_monitor.evaluation.runs.run_one` (the monitor and two baselines on the
same samples, scored against the run's truth); the campaign's tables are Wan2018 sec. VI-B's
(:mod:`gcs_monitor.fdi.metrics`): false-alarm, missed-detection and false-isolation rates and
detection delay, per channel kind and method; :func:`~gcs_monitor.evaluation.report.write_report`
writes them with the per-run CSVs and plots.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from pathlib import Path

from gcs_monitor.config import MonitorConfig
from gcs_monitor.evaluation import scenarios
from gcs_monitor.evaluation.configs import consensus_config, without_actuators
from gcs_monitor.evaluation.records import CampaignResult, RunRecord
from gcs_monitor.evaluation.report import write_report
from gcs_monitor.evaluation.runner import run_parallel
from gcs_monitor.evaluation.runs import run_one
from gcs_monitor.evaluation.scoring import tables_of
from sim_vehicle.scenario import Scenario


def _example_index(scs: Sequence[Scenario]) -> int:
    """The run whose residual RMS is plotted: the first single bias fault, else the first
    faulty run, else run 0."""
    for i, sc in enumerate(scs):
        if len(sc.faults) == 1 and sc.faults[0].kind == "bias":
            return i
    return next((i for i, sc in enumerate(scs) if sc.faults), 0)


def _campaign_run(job: tuple[int, Scenario, MonitorConfig, bool, bool]) -> RunRecord:
    index, sc, cfg, keep, declare = job
    return run_one(index, sc, cfg, keep_series=keep, declare_weather=declare)


def run_records(scs: Sequence[Scenario], cfg: MonitorConfig, jobs: int, *,
                progress: bool = True, desc: str = "campaign",
                declare_weather: bool = True) -> list[RunRecord]:
    """Run every scenario (``jobs`` worker processes); records in scenario order, the example
    run (:func:`_example_index`) with its series. ``declare_weather`` False gives the monitor
    no forecast: it keeps ``cfg``'s ``[airdata.weather]`` and estimates the weather from the
    flight (:mod:`gcs_monitor.families.airdata.weather`)."""
    ex = _example_index(scs)
    work = [(i, sc, cfg, i == ex, declare_weather) for i, sc in enumerate(scs)]
    return run_parallel(_campaign_run, work, jobs, desc=desc, progress=progress)


def run_campaign(preset_set: str, runs: int, jobs: int, out_dir: Path, *, seed: int = 0,
                 progress: bool = True, config: MonitorConfig | None = None,
                 declare_weather: bool = True) -> CampaignResult:
    """Run ``runs`` scenarios of a preset set through the monitor and the baselines.

    Parameters
    ----------
    preset_set : name from :func:`sim_vehicle.campaigns.list_preset_sets`
    runs : number of runs (scenario list is deterministic for ``(runs, seed)``)
    jobs : worker processes
    out_dir : where report.md, metrics.csv, runs.csv, faults.csv and the PNG plots go
    seed : preset-set seed
    progress : tqdm progress bar
    config : monitor configuration (default: the :class:`MonitorConfig` defaults without the
        actuator family, which these air-data campaigns do not judge)
    declare_weather : give each run its scenario's weather as a forecast (``[airdata.weather]``);
        False: no forecast, the monitor estimates the weather from the flight

    Returns
    -------
    CampaignResult with ``.markdown`` (the report) and ``.tables`` (Table IV rows per method)
    """
    cfg = config or without_actuators(MonitorConfig())
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    records = run_records(scenarios.preset_set(preset_set, runs, seed), cfg, jobs,
                          progress=progress, desc=preset_set, declare_weather=declare_weather)
    res = CampaignResult(preset_set=preset_set, n_runs=runs, seed=seed, config=cfg,
                         declare_weather=declare_weather,
                         runs=records, tables=tables_of(records), markdown="", out_dir=out,
                         files=[], wall_s=time.perf_counter() - t0)
    res.markdown, res.files = write_report(res, jobs=jobs)
    return res


def triplex_fdi(out_dir: Path, jobs: int = 1, quick: bool = False) -> str:
    """The triplex preset campaign twice: with the default air-data estimator (CMHE
    reference) and with consensus alone (no estimator); FAR, MDR, FIR and delays."""
    n = 12 if quick else 120
    a = run_campaign("triplex", n, jobs, Path(out_dir) / "triplex_default")
    b = run_campaign("triplex", n, jobs, Path(out_dir) / "triplex_consensus",
                     config=consensus_config())
    return a.markdown + "\n\n" + b.markdown


def experiments() -> dict[str, Callable[[Path, int, bool], str]]:
    """Named experiments for ``gcs-monitor evaluate --experiment`` (registry hook)."""
    return {"triplex_fdi": triplex_fdi}
