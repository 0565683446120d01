"""Campaign harness: simulate preset-set runs, monitor them, score the alarms against truth.

Each run goes through the same chain as live data: ``sim_vehicle.run.iter_run`` produces
MAVLink-encoded packets, :class:`~gcs_monitor.monitor.Monitor` decodes and monitors them. The
alarm events (what the journal would hold) are compared with the ground truth: the fault
intervals per channel from the scenario, and the fault value actually applied per sample
(``run_state.suite.fault_log``). Scores are Wan2018 sec. VI-B's (:mod:`gcs_monitor.fdi.metrics`):
false-alarm, missed-detection and false-isolation rates and detection delay, per channel kind.

Baselines run on the same samples: every air-data sample the monitor's redundant sets see is
also fed to median selection with a persistence-confirmed comparison monitor
(:class:`~gcs_monitor.fdi.baselines.MedianVoteMonitor`, the industrial triplex voter) and to a
fixed threshold on the raw difference to the median
(:func:`~gcs_monitor.fdi.baselines.fixed_threshold_monitor`). Both use the monitor's J_th of the
set as their threshold on ``|y_i - median|``.

Besides the alarm scores, per run:

* fault reconstruction RMSE per faulty channel: RMS over the fault interval of
  ``(y_i - reference) - f_i`` where ``reference`` is what the set's residuals are taken against
  (the MHE prediction, or the consensus) and ``f_i`` the applied fault (truth);
* output error per set and method: RMS of ``fused - true`` (the value handed on downstream:
  adaptive weighted fusion, median selection) and of the MHE's virtual sensor;
* fault-free residual statistics: the largest J per set and what
  :func:`gcs_monitor.fdi.monitor.calibrate` would set J_th to (over fault-free runs only).

This module drives the simulator (``sim_vehicle``): evaluation needs ground truth.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import multiprocessing
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gcs_monitor.config import AirDataConfig, MonitorConfig, scheduled_threshold
from gcs_monitor.core.types import ChannelId
from gcs_monitor.core.units import KT2MPS
from gcs_monitor.fdi.baselines import MedianVoteMonitor, MedianVoteParams, fixed_threshold_monitor
from gcs_monitor.fdi.events import AlarmEvent, AlarmKind, AlarmState
from gcs_monitor.fdi.metrics import MetricsRow, RunOutcome, evaluate_run, metrics_table
from gcs_monitor.fdi.monitor import calibrate
from gcs_monitor.monitor import Monitor
from sim_vehicle.run import RunState, iter_run

log = logging.getLogger(__name__)

AIR_SETS = ("aoa", "cas")
IMU_GROUPS = ("acc", "gyro")
METHOD_MONITOR = "monitor"
METHOD_MEDIAN = "median_vote"
METHOD_FIXED = "fixed_threshold"
METHODS = (METHOD_MONITOR, METHOD_MEDIAN, METHOD_FIXED)
GRACE_US = 1_000_000  # a latched alarm raised up to 1 s after a fault ended still counts
CHUNK_PACKETS = 64  # packets per Monitor.feed (a UDP/tlog reader hands over similar chunks)
CALIBRATE_K = 1.5  # calibrate(rule="max") margin over the worst fault-free J


@dataclass(frozen=True, slots=True)
class FaultTruth:
    """One injected sensor fault of a run."""

    channel: ChannelId
    kind: str
    t_start_us: int
    t_end_us: int | None


@dataclass(frozen=True, slots=True)
class FaultResult:
    """How one method did on one injected fault."""

    method: str
    channel: str
    kind: str
    detected: bool
    delay_s: float  # NaN when missed


@dataclass
class RunRecord:
    """Everything one run produced (small and picklable: workers send it to the parent)."""

    index: int
    name: str
    seed: int
    duration_s: float
    manoeuvre: str
    wind: str
    faults: list[FaultTruth]
    outcomes: dict[str, dict[str, RunOutcome]]  # method -> group -> outcome
    fault_results: list[FaultResult]
    raised: dict[str, int]  # method -> number of counted RAISED events
    recon_rmse: dict[str, float]  # faulty channel -> reconstruction RMSE (monitor), SI
    output_rmse: dict[str, dict[str, float]]  # method -> set -> RMS(output - truth), SI
    output_lost: dict[str, dict[str, int]]  # method -> set -> samples without an output
    j_max: dict[str, float]  # group -> largest J of never-faulted channels, SI
    j_calibrated: dict[str, float]  # set -> calibrate(rule="max") on never-faulted instances
    wall_s: float
    events: list[AlarmEvent] = field(default_factory=list)  # the monitor's alarm events
    series: dict[str, np.ndarray] | None = None  # per air sample (example plot)

    @property
    def faulty(self) -> bool:
        return bool(self.faults)


@dataclass
class CampaignResult:
    """A finished campaign: per-run records, Wan2018 Table IV rows per method, report."""

    preset_set: str
    n_runs: int
    seed: int
    config: MonitorConfig
    runs: list[RunRecord]
    tables: dict[str, list[MetricsRow]]
    markdown: str
    out_dir: Path
    files: list[Path]
    wall_s: float

    def row(self, method: str, group: str) -> MetricsRow:
        return next(r for r in self.tables[method] if r.group == group)


def channel_of(name: str) -> ChannelId | None:
    """Scenario channel name -> monitored ChannelId (air data only: ``aoa1`` -> aoa/1)."""
    for kind in AIR_SETS:
        if name.startswith(kind) and name[len(kind):].isdigit():
            return ChannelId(kind, int(name[len(kind):]))
    return None


def fault_truth(sc: Any) -> list[FaultTruth]:
    """The scenario's air-data sensor faults as monitored channels and µs intervals."""
    out = []
    for f in sc.faults:
        ch = channel_of(f.channel)
        if ch is None:
            continue
        end = None if f.t_end_s is None else round(f.t_end_s * 1e6)
        out.append(FaultTruth(ch, f.kind, round(f.t_start_s * 1e6), end))
    return out


def truth_intervals(faults: Sequence[FaultTruth]) -> dict[ChannelId, list[tuple[int, int | None]]]:
    out: dict[ChannelId, list[tuple[int, int | None]]] = {}
    for f in faults:
        out.setdefault(f.channel, []).append((f.t_start_us, f.t_end_us))
    return out


def score_faults(method: str, events: Sequence[AlarmEvent],
                 faults: Sequence[FaultTruth]) -> list[FaultResult]:
    """Per injected fault: detected (a counted RAISED on its channel inside its interval) and
    the delay from fault start, s. Same reading as :func:`gcs_monitor.fdi.metrics.evaluate_run`."""
    raised = sorted((e.t_us, e.channel) for e in events
                    if e.state is AlarmState.RAISED
                    and e.kind in (AlarmKind.SENSOR_FAULT, AlarmKind.ACTUATOR_FAULT))
    out = []
    for f in faults:
        hit = next((t for t, c in raised if c == f.channel and t >= f.t_start_us
                    and (f.t_end_us is None or t <= f.t_end_us + GRACE_US)), None)
        out.append(FaultResult(method, str(f.channel), f.kind, hit is not None,
                               math.nan if hit is None else (hit - f.t_start_us) * 1e-6))
    return out


class _AirRecorder:
    """Per air-data sample: feeds the baselines and keeps what the scores need."""

    def __init__(self, cfg: MonitorConfig) -> None:
        self.stale_s = cfg.telemetry.stale_after_s
        sigma = cfg.airdata.turbulence_sigma_mps  # the baselines get the monitor's J_th
        th = {"aoa": scheduled_threshold(cfg.fdi.aoa, sigma),
              "cas": scheduled_threshold(cfg.fdi.cas, sigma)}
        persistence = {"aoa": cfg.fdi.aoa.n_detect, "cas": cfg.fdi.cas.n_detect}
        self.baselines: dict[str, dict[str, MedianVoteMonitor]] = {
            METHOD_MEDIAN: {s: MedianVoteMonitor(s, 3, MedianVoteParams(
                threshold=th[s], persistence_n=persistence[s]), estimator=METHOD_MEDIAN)
                for s in AIR_SETS},
            METHOD_FIXED: {s: fixed_threshold_monitor(s, 3, th[s], estimator=METHOD_FIXED)
                           for s in AIR_SETS},
        }
        self.events: dict[str, list[AlarmEvent]] = {m: [] for m in self.baselines}
        self.t: list[int] = []
        self.rows: dict[str, list[list[float]]] = {}  # name -> per sample values
        self.j_max: dict[str, float] = {}

    def _put(self, key: str, values: Sequence[float]) -> None:
        self.rows.setdefault(key, []).append(list(values))

    def __call__(self, sysid: int, frame: Any, step: Any) -> None:
        for cs in step.channels:
            k = cs.channel.kind
            if cs.rms > self.j_max.get(k, -1.0):
                self.j_max[k] = cs.rms
        if not step.sets:
            return
        self.t.append(frame.t_us)
        virtual = None
        for e in step.estimates:
            if e.virtual:
                virtual = e.virtual
        for st in step.sets:
            s = st.name
            meas = frame.aoa_rad if s == "aoa" else frame.cas_mps
            age = frame.aoa_age_s if s == "aoa" else frame.cas_age_s
            valid = np.isfinite(meas) & (age < self.stale_s)
            self._put(f"{s}.measured", st.measured)
            self._put(f"{s}.ref", (st.reference,))
            self._put(f"{s}.{METHOD_MONITOR}.fused", (st.fused,))
            self._put(f"{s}.rms", st.rms)
            self._put(f"{s}.faulty", [float(x) for x in st.faulty])
            v = math.nan
            if virtual is not None:
                v = next((x for c, x in virtual.items() if c.kind == f"{s}_virtual"), math.nan)
            self._put(f"{s}.virtual.fused", (v,))
            for m, mons in self.baselines.items():
                bs, ev = mons[s].step(frame.t_us, meas[:3], valid[:3])
                self._put(f"{s}.{m}.fused", (bs.fused,))
                if ev:
                    self.events[m] += ev

    def arrays(self) -> dict[str, np.ndarray]:
        out = {k: np.asarray(v, dtype=float) for k, v in self.rows.items()}
        out["t_us"] = np.asarray(self.t, dtype=np.int64)
        return out


def _sample_at(ts_s: np.ndarray, vals: np.ndarray, t_s: np.ndarray) -> np.ndarray:
    """Latest logged value at or before each time (zero before the first sample)."""
    idx = np.searchsorted(ts_s, t_s + 1e-9, side="right") - 1
    return np.where(idx >= 0, vals[np.clip(idx, 0, None)], 0.0) if len(ts_s) else np.zeros_like(t_s)


def _rms(x: np.ndarray) -> float:
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(x * x))) if x.size else math.nan


def _ceil_to(x: float, step: float) -> float:
    return math.ceil(round(abs(x) / step, 9)) * step


def declared_weather(sc: Any, base: AirDataConfig | None = None) -> AirDataConfig:
    """The weather a scenario declares, as the monitor receives it (a forecast).

    Built from the scenario's wind *specification* (kind, steady wind, shear amplitude, Dryden
    intensity and scale), never from the simulated wind samples, and coarsened as a forecast
    is: wind speed (not direction) rounded up to 5 kt, vertical wind to 1 kt, shear to 5 kt,
    turbulence intensity to 1 kt. Shear acceleration: the simulator's microburst
    (``sim_vehicle.environment.wind``) changes the wind by ``A`` over ``SHEAR_DURATION_S`` along
    ``A/2 (1 - cos(2 pi t / T))``, whose largest rate is ``pi A / T``. The other envelope fields
    (``n_sigma``, flight path) come from ``base``.
    """
    from sim_vehicle.environment.wind import SHEAR_DURATION_S, SHEAR_VERTICAL_RATIO

    b = base or AirDataConfig()
    w = sc.wind
    kt = KT2MPS
    mean = (0.0, 0.0, 0.0) if w.kind == "calm" else w.mean_ned_mps
    wind = _ceil_to(math.hypot(mean[0], mean[1]) / kt, 5.0) * kt
    wind_z = _ceil_to(mean[2] / kt, 1.0) * kt
    shear = shear_z = shear_rate = 0.0
    if "shear" in w.kind:
        shear = _ceil_to(w.shear_amplitude_mps / kt, 5.0) * kt
        shear_z = SHEAR_VERTICAL_RATIO * shear
        shear_rate = math.pi * shear / SHEAR_DURATION_S
    sigma = _ceil_to(w.turbulence_sigma_mps / kt, 1.0) * kt if "turbulence" in w.kind else 0.0
    return dataclasses.replace(b, wind_mps=wind, wind_z_mps=wind_z, shear_mps=shear,
                               shear_z_mps=shear_z, shear_rate_mps2=shear_rate,
                               turbulence_sigma_mps=sigma,
                               turbulence_scale_m=w.turbulence_scale_m)


def run_one(index: int, sc: Any, cfg: MonitorConfig, *, keep_series: bool = False,
            declare_weather: bool = True) -> RunRecord:
    """Simulate one scenario, monitor its MAVLink bytes, score the run against its truth.

    With ``declare_weather`` the monitor receives the scenario's declared weather
    (:func:`declared_weather`) as its ``[airdata]`` envelope, as a flight receives its
    forecast; otherwise ``cfg.airdata`` is used as given.
    """
    t0 = time.perf_counter()
    if declare_weather:
        cfg = dataclasses.replace(cfg, airdata=declared_weather(sc, cfg.airdata))
    rec = _AirRecorder(cfg)
    mon = Monitor(cfg, on_step=rec)
    rs = RunState()
    buf: list[bytes] = []
    for _, _, pkt in iter_run(sc, record_truth=True, run_state=rs):
        buf.append(pkt)
        if len(buf) >= CHUNK_PACKETS:
            mon.feed(b"".join(buf))
            buf.clear()
    mon.feed(b"".join(buf))
    mon.finish()
    assert rs.truth is not None and rs.suite is not None

    faults = fault_truth(sc)
    intervals = truth_intervals(faults)
    imu_on = cfg.estimators.imu_ts or cfg.estimators.imu_hosm
    groups = AIR_SETS + (IMU_GROUPS if imu_on else ())
    outcomes = {METHOD_MONITOR: evaluate_run(mon.events, intervals, groups=groups,
                                             grace_us=GRACE_US)}
    results = score_faults(METHOD_MONITOR, mon.events, faults)
    raised = {METHOD_MONITOR: _n_raised(mon.events)}
    for m, ev in rec.events.items():
        outcomes[m] = evaluate_run(ev, intervals, groups=AIR_SETS, grace_us=GRACE_US)
        results += score_faults(m, ev, faults)
        raised[m] = _n_raised(ev)

    a = rec.arrays()
    t_s = a["t_us"] * 1e-6
    tr = rs.truth.arrays()
    truth = {"aoa": np.interp(t_s, tr["state.t_s"], tr["state.aoa_rad"]),
             "cas": np.interp(t_s, tr["state.t_s"], tr["state.cas_mps"])}
    recon: dict[str, float] = {}
    for f in faults:
        s, i = f.channel.kind, f.channel.instance
        if f"{s}.measured" not in a:
            continue
        ts, vals = rs.suite.fault_log.get(f"{s}{i}", ([], []))
        fv = _sample_at(np.asarray(ts, dtype=float), np.asarray(vals, dtype=float), t_s)
        inside = (a["t_us"] >= f.t_start_us) & (
            True if f.t_end_us is None else a["t_us"] < f.t_end_us)
        r = a[f"{s}.measured"][:, i] - a[f"{s}.ref"][:, 0]
        recon[str(f.channel)] = _rms((r - fv)[inside])
    out_rmse: dict[str, dict[str, float]] = {}
    out_lost: dict[str, dict[str, int]] = {}
    for m in (METHOD_MONITOR, "virtual", METHOD_MEDIAN, METHOD_FIXED):
        for s in AIR_SETS:
            key = f"{s}.{m}.fused"
            if key not in a:
                continue
            v = a[key][:, 0]
            if m == "virtual" and not np.isfinite(v).any():
                continue
            out_rmse.setdefault(m, {})[s] = _rms(v - truth[s])
            out_lost.setdefault(m, {})[s] = int(np.sum(~np.isfinite(v)))
    j_max = dict(rec.j_max)
    j_cal: dict[str, float] = {}
    faulted = {f.channel for f in faults}
    n_eval = {"aoa": cfg.fdi.aoa.n_eval, "cas": cfg.fdi.cas.n_eval}
    for s in AIR_SETS:
        if f"{s}.rms" not in a:
            continue
        healthy = [i for i in range(a[f"{s}.rms"].shape[1]) if ChannelId(s, i) not in faulted]
        if healthy:
            j_max[s] = float(np.nanmax(a[f"{s}.rms"][:, healthy]))
            r = a[f"{s}.measured"][:, healthy] - a[f"{s}.ref"]
            cal = [calibrate(r[:, k], rms_window_n=n_eval[s], k=CALIBRATE_K)
                   for k in range(len(healthy)) if np.isfinite(r[:, k]).sum() >= n_eval[s]]
            if cal:
                j_cal[s] = max(cal)
    series = None
    if keep_series:
        series = dict(a)
        for s in AIR_SETS:
            series[f"{s}.true"] = truth[s]
    return RunRecord(
        index=index, name=sc.name, seed=sc.seed, duration_s=sc.duration_s,
        manoeuvre=sc.manoeuvre.kind, wind=sc.wind.kind, faults=faults, outcomes=outcomes,
        fault_results=results, raised=raised, recon_rmse=recon, output_rmse=out_rmse,
        output_lost=out_lost, j_max=j_max, j_calibrated=j_cal,
        wall_s=time.perf_counter() - t0, events=list(mon.events), series=series,
    )


def _n_raised(events: Sequence[AlarmEvent]) -> int:
    return sum(1 for e in events if e.state is AlarmState.RAISED
               and e.kind in (AlarmKind.SENSOR_FAULT, AlarmKind.ACTUATOR_FAULT))


def _worker(job: tuple[int, Any, MonitorConfig, bool]) -> RunRecord:
    index, sc, cfg, keep = job
    return run_one(index, sc, cfg, keep_series=keep)


def _example_index(scenarios: Sequence[Any]) -> int:
    """The run whose residual RMS is plotted: the first single bias fault, else the first
    faulty run, else run 0."""
    for i, sc in enumerate(scenarios):
        if len(sc.faults) == 1 and sc.faults[0].kind == "bias":
            return i
    return next((i for i, sc in enumerate(scenarios) if sc.faults), 0)


def run_records(scenarios: Sequence[Any], cfg: MonitorConfig, jobs: int, *,
                progress: bool = True, desc: str = "campaign") -> list[RunRecord]:
    """Run every scenario (``jobs`` worker processes); records in scenario order."""
    import sim_vehicle.physics  # noqa: F401  (imported before the workers fork)
    from gcs_monitor.monitor import build_estimators

    build_estimators(cfg)  # imports the estimator modules in the parent, too
    ex = _example_index(scenarios)
    work = [(i, sc, cfg, i == ex) for i, sc in enumerate(scenarios)]
    bar: Any = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(work), unit="run", desc=desc)
    records: list[RunRecord] = []
    try:
        if jobs <= 1:
            for w in work:
                records.append(_worker(w))
                if bar is not None:
                    bar.update(1)
        else:
            # fork: workers share the modules the parent imported, so a campaign runs one
            # version of the code even if files change while it runs
            os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
            ctx = multiprocessing.get_context("fork")
            with ctx.Pool(jobs) as pool:
                for r in pool.imap_unordered(_worker, work):
                    records.append(r)
                    if bar is not None:
                        bar.update(1)
    finally:
        if bar is not None:
            bar.close()
    records.sort(key=lambda r: r.index)
    return records


def tables_of(records: Sequence[RunRecord]) -> dict[str, list[MetricsRow]]:
    """Wan2018 Table IV rows per method."""
    methods = [m for m in METHODS if records and m in records[0].outcomes]
    return {m: metrics_table([r.outcomes[m] for r in records]) for m in methods}


def run_campaign(preset_set: str, runs: int, jobs: int, out_dir: Path, *, seed: int = 0,
                 progress: bool = True, config: MonitorConfig | None = None) -> CampaignResult:
    """Run ``runs`` scenarios of a preset set through the monitor and the baselines.

    Parameters
    ----------
    preset_set : name from :func:`sim_vehicle.campaigns.list_preset_sets`
    runs : number of runs (scenario list is deterministic for ``(runs, seed)``)
    jobs : worker processes
    out_dir : where report.md, metrics.csv, runs.csv, faults.csv and the PNG plots go
    seed : preset-set seed
    progress : tqdm progress bar
    config : monitor configuration (default: :class:`MonitorConfig` defaults)

    Returns
    -------
    CampaignResult with ``.markdown`` (the report) and ``.tables`` (Table IV rows per method)
    """
    from gcs_monitor.evaluation.report import write_report
    from sim_vehicle.campaigns import generate_set

    cfg = config or MonitorConfig()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    scenarios = generate_set(preset_set, runs, seed)
    records = run_records(scenarios, cfg, jobs, progress=progress, desc=preset_set)
    tables = tables_of(records)
    wall = time.perf_counter() - t0
    res = CampaignResult(preset_set=preset_set, n_runs=runs, seed=seed, config=cfg,
                         runs=records, tables=tables, markdown="", out_dir=out, files=[],
                         wall_s=wall)
    res.markdown, res.files = write_report(res, jobs=jobs)
    return res


def calibrate_thresholds(runs: int, jobs: int, *, seed: int = 1000,
                         config: MonitorConfig | None = None,
                         progress: bool = True) -> dict[str, float]:
    """J_th per air-data set from fault-free runs (``fault_free`` preset set, seeds separate
    from the evaluation's): the largest :func:`calibrate` (rule "max", k = 1.5) over runs."""
    from sim_vehicle.campaigns import generate_set

    cfg = config or MonitorConfig()
    recs = run_records(generate_set("fault_free", runs, seed), cfg, jobs, progress=progress,
                       desc="calibrate")
    return {s: max((r.j_calibrated[s] for r in recs if s in r.j_calibrated), default=math.nan)
            for s in AIR_SETS}


def experiments() -> dict[str, Callable[[Path, int, bool], str]]:
    """Named experiments for ``gcs-monitor evaluate --experiment`` (registry hook)."""

    def triplex(out: Path, jobs: int, quick: bool) -> str:
        """The triplex preset campaign twice: with the default air-data estimator (CMHE
        reference) and with consensus alone (no estimator); FAR, MDR, FIR and delays."""
        import dataclasses

        from gcs_monitor.config import EstimatorsConfig

        n = 12 if quick else 120
        a = run_campaign("triplex", n, jobs, Path(out) / "triplex_default")
        cfg = MonitorConfig()
        cfg = dataclasses.replace(cfg, estimators=dataclasses.replace(
            cfg.estimators, airdata="none"))
        assert isinstance(cfg.estimators, EstimatorsConfig)
        b = run_campaign("triplex", n, jobs, Path(out) / "triplex_consensus", config=cfg)
        return a.markdown + "\n\n" + b.markdown

    return {"triplex_fdi": triplex}
