"""One run through the MAVLink path: simulator (or tlog) -> bytes -> :class:`Monitor` -> capture.

Every run goes through the same chain as live data: ``sim_vehicle.run.iter_run`` produces
MAVLink-encoded packets (or a tlog is read), :class:`~gcs_monitor.monitor.Monitor` decodes and
monitors them, and ``Monitor(on_step=...)`` captures what the scores need per sample:

* air data (:func:`run_one`): per air-data sample the set statuses, the MHE's virtual sensor and
  two baselines fed the same samples -- median selection with a persistence-confirmed
  comparison monitor (:class:`~gcs_monitor.fdi.baselines.MedianVoteMonitor`, the industrial
  triplex voter) and a fixed threshold on the raw difference to the median
  (:func:`~gcs_monitor.fdi.baselines.fixed_threshold_monitor`), both with the monitor's J_th of
  the set as their threshold on ``|y_i - median|``; scored by
  :func:`~gcs_monitor.evaluation.scoring.score_air_run`;
* IMU (:func:`simulate_imu`, :func:`replay_packets`): the fault estimates of every IMU
  estimator per Frame; the true fault is the simulator's ``suite.fault_log``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from gcs_monitor.config import MonitorConfig
from gcs_monitor.evaluation.configs import (
    AirDataVariant,
    ImuVariants,
    airdata_of,
    detect_n,
    families_for,
    imu_config,
    sim_air_period_s,
    with_declared_weather,
)
from gcs_monitor.evaluation.records import (
    AIR_SETS,
    METHOD_FIXED,
    METHOD_MEDIAN,
    METHOD_MONITOR,
    ImuRun,
    RunRecord,
)
from gcs_monitor.evaluation.scoring import imu_fault_truth, imu_fault_windows, score_air_run
from gcs_monitor.families.imu.imu_ts import FAULT_CHANNELS
from gcs_monitor.fdi.baselines import MedianVoteMonitor, MedianVoteParams, fixed_threshold_monitor
from gcs_monitor.fdi.config import scheduled_threshold
from gcs_monitor.fdi.events import AlarmEvent, AlarmKind
from gcs_monitor.fdi.records import StepOutput
from gcs_monitor.link.transports import TlogSource
from gcs_monitor.monitor import Monitor
from sim_vehicle.run import RunState, iter_run
from sim_vehicle.scenario import Scenario

CHUNK_PACKETS = 64  # packets per Monitor.feed (a UDP/tlog reader hands over similar chunks)


def feed_packets(mon: Monitor, packets: Iterable[bytes]) -> None:
    """Feed packets to ``mon`` in chunks of :data:`CHUNK_PACKETS`, then finish it."""
    buf: list[bytes] = []
    for pkt in packets:
        buf.append(pkt)
        if len(buf) >= CHUNK_PACKETS:
            mon.feed(b"".join(buf))
            buf = []
    mon.feed(b"".join(buf))
    mon.finish()


def tlog_chunks(path: Path) -> list[bytes]:
    """The byte chunks of a tlog, as ``gcs-monitor replay`` reads them."""
    with TlogSource(path) as src:
        return [chunk for chunk, _ in src]


# ------------------------------------------------------------------------------------------------
# air data
# ------------------------------------------------------------------------------------------------


class AirCapture:
    """``Monitor.on_step`` callback: per air-data sample, feeds the baselines and keeps what the
    scores need. The baselines get the monitor's J_th and, as the median vote's persistence,
    its n_D in samples of the air-data stream (period ``air_period_s``)."""

    def __init__(self, cfg: MonitorConfig, air_period_s: float) -> None:
        self.stale_s = cfg.telemetry.stale_after_s
        air = airdata_of(cfg)
        sigma = air.weather.turbulence_sigma_mps
        th = {"aoa": scheduled_threshold(air.fdi.aoa, sigma),
              "cas": scheduled_threshold(air.fdi.cas, sigma)}
        persistence = {"aoa": detect_n(air.fdi.aoa, air_period_s),
                       "cas": detect_n(air.fdi.cas, air_period_s)}
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

    def __call__(self, sysid: int, frame: Any, step: StepOutput) -> None:
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


def run_one(index: int, sc: Scenario, cfg: MonitorConfig, *, keep_series: bool = False,
            declare_weather: bool = True) -> RunRecord:
    """Simulate one scenario, monitor its MAVLink bytes, score the run against its truth.

    With ``declare_weather`` the monitor receives the scenario's declared weather
    (:func:`~gcs_monitor.evaluation.configs.declared_weather`) as its ``[airdata.weather]``,
    as a flight receives its forecast; otherwise ``cfg``'s weather is used as given.
    """
    t0 = time.perf_counter()
    if declare_weather:
        cfg = with_declared_weather(cfg, sc)
    cap = AirCapture(cfg, sim_air_period_s(sc))
    mon = Monitor(cfg, on_step=cap)
    rs = RunState()
    feed_packets(mon, (pkt for _, _, pkt in iter_run(sc, record_truth=True, run_state=rs)))
    assert rs.truth is not None and rs.suite is not None
    rec = score_air_run(index, sc, cfg, mon.events, cap.events, cap.arrays(), cap.j_max,
                        rs.truth.arrays(), rs.suite.fault_log, keep_series=keep_series,
                        wall_s=0.0)
    rec.wall_s = time.perf_counter() - t0
    return rec


def replay_tlog(path: Path, cfg: MonitorConfig, make_airdata: AirDataVariant
                ) -> tuple[list[AlarmEvent], dict[str, np.ndarray]]:
    """Monitor a tlog (as ``gcs-monitor replay``) with ``cfg``'s families, the air-data family
    running the estimator ``make_airdata()``; the alarm events and per air-data sample: ``t``
    (s), ``aoa_j``/``cas_j`` (J per instance) and ``aoa_est``/``cas_est`` (the estimator's
    virtual sensor), SI."""
    rows: dict[str, list[Any]] = {k: [] for k in ("t", "aoa_j", "cas_j", "aoa_est", "cas_est")}

    def on_step(sysid: int, frame: Any, step: StepOutput) -> None:
        if not step.sets:
            return
        rows["t"].append(frame.t_us * 1e-6)
        for st in step.sets:
            rows[f"{st.name}_j"].append(st.rms)
        v: dict[Any, float] = next((e.virtual for e in step.estimates if e.virtual), {})
        rows["aoa_est"].append(next((x for c, x in v.items() if c.kind == "aoa_virtual"),
                                    math.nan))
        rows["cas_est"].append(next((x for c, x in v.items() if c.kind == "cas_virtual"),
                                    math.nan))

    mon = Monitor(cfg, families_for=families_for(cfg, airdata=make_airdata), on_step=on_step)
    for data in tlog_chunks(path):
        mon.feed(data)
    mon.finish()
    return list(mon.events), {k: np.asarray(v, dtype=float) for k, v in rows.items()}


# ------------------------------------------------------------------------------------------------
# IMU
# ------------------------------------------------------------------------------------------------


class ImuCapture:
    """``Monitor.on_step`` callback: fault estimates per Frame, per estimator name."""

    def __init__(self) -> None:
        self.t_us: list[int] = []
        self.rows: dict[str, list[list[float]]] = {}

    def __call__(self, sysid: int, frame: Any, step: StepOutput) -> None:
        k = len(self.t_us)
        self.t_us.append(frame.t_us)
        for e in step.estimates:
            if not e.available:
                continue
            if not all(c in e.faults for c in FAULT_CHANNELS):
                continue  # not an IMU estimator (air data)
            rows = self.rows.setdefault(e.name, [])
            rows.extend([[math.nan] * 6] * (k - len(rows)))
            if len(rows) == k:
                rows.append([e.faults[c] for c in FAULT_CHANNELS])

    def arrays(self) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        n = len(self.t_us)
        out = {}
        for name, rows in self.rows.items():
            rows = rows + [[math.nan] * 6] * (n - len(rows))
            out[name] = np.asarray(rows, dtype=np.float64)
        return np.asarray(self.t_us, dtype=np.int64) * 1e-6, out


def replay_packets(packets: Iterable[bytes], cfg: MonitorConfig | None = None,
                   variants: ImuVariants | None = None, *,
                   notices: list[AlarmEvent] | None = None
                   ) -> tuple[np.ndarray, dict[str, np.ndarray], list[AlarmEvent]]:
    """Feed MAVLink packets through a Monitor; return Frame times, f_hat per estimator, alarms.

    ``cfg`` defaults to :func:`~gcs_monitor.evaluation.configs.imu_config` (air-data estimation
    off, the IMU family's defaults); ``variants``, if given, replaces the IMU family's
    estimators (:func:`~gcs_monitor.evaluation.configs.lu2016_variants`, ...). ``notices``: if
    given, the ESTIMATOR events (re-initialisation notices, never alarms) are appended to it.
    """
    cap = ImuCapture()
    cfg = cfg or imu_config()
    mon = Monitor(cfg, families_for=families_for(cfg, imu=variants), on_step=cap)
    feed_packets(mon, packets)
    t_s, f_hat = cap.arrays()
    events = [e for e in mon.events if e.kind == AlarmKind.SENSOR_FAULT
              and e.channel.kind in ("acc", "gyro")]
    if notices is not None:
        notices += [e for e in mon.events if e.kind == AlarmKind.ESTIMATOR]
    return t_s, f_hat, events


def simulate_imu(sc: Scenario, cfg: MonitorConfig | None = None,
                 variants: ImuVariants | None = None) -> ImuRun:
    """Run a scenario through the simulator, the MAVLink bytes and the Monitor (``cfg`` and
    ``variants`` as :func:`replay_packets`)."""
    t0 = time.perf_counter()
    rs = RunState()
    packets = (pkt for _, _, pkt in iter_run(sc, run_state=rs))
    t_s, f_hat, events = replay_packets(packets, cfg, variants)
    assert rs.suite is not None
    return ImuRun(name=f"{sc.name}_s{sc.seed}", t_s=t_s, f_hat=f_hat,
                  f_true=imu_fault_truth(t_s, rs.suite.fault_log), events=events,
                  fault_windows=imu_fault_windows(sc), duration_s=sc.duration_s,
                  wall_s=time.perf_counter() - t0)
