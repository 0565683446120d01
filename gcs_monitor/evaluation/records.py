"""What runs and campaigns produce: plain, picklable records (workers send them to the parent),
and the channel names and display scales they are read with.

No behaviour here beyond trivial properties: :mod:`~gcs_monitor.evaluation.runs` fills them,
:mod:`~gcs_monitor.evaluation.scoring` scores them, :mod:`~gcs_monitor.evaluation.report`
writes them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gcs_monitor.config import MonitorConfig
from gcs_monitor.core.types import ChannelId
from gcs_monitor.core.units import DEG2RAD, KT2MPS, RAD2DEG
from gcs_monitor.fdi.events import AlarmEvent
from gcs_monitor.fdi.metrics import MetricsRow, RunOutcome

AIR_SETS = ("aoa", "cas")
IMU_GROUPS = ("acc", "gyro")
METHOD_MONITOR = "monitor"
METHOD_MEDIAN = "median_vote"
METHOD_FIXED = "fixed_threshold"
METHODS = (METHOD_MONITOR, METHOD_MEDIAN, METHOD_FIXED)
# the simulator's IMU fault channels, in the order of the estimators' FAULT_CHANNELS
SIM_CHANNELS = ("imu0.acc.x", "imu0.acc.y", "imu0.acc.z",
                "imu0.gyro.p", "imu0.gyro.q", "imu0.gyro.r")
AXES = ("Ax", "Ay", "Az", "p", "q", "r")
# report accelerometer channels in m/s^2, gyro channels in deg/s
REPORT_SCALE = np.array([1.0, 1.0, 1.0, RAD2DEG, RAD2DEG, RAD2DEG])
# display unit per channel group: (label, SI per display unit); display value = SI / factor
UNITS = {"aoa": ("deg", DEG2RAD), "cas": ("kt", KT2MPS), "acc": ("m/s²", 1.0),
         "gyro": ("deg/s", DEG2RAD)}


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
    """Everything one air-data run produced, scored against its truth."""

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
    declare_weather: bool = True  # each run's weather given as a forecast; False: estimated

    def row(self, method: str, group: str) -> MetricsRow:
        return next(r for r in self.tables[method] if r.group == group)


@dataclass
class ImuRun:
    """Per-Frame capture of one IMU run.

    t_s : (n,) Frame times, s
    f_hat : estimator name -> (n, 6) fault estimates, SI (NaN where unavailable)
    f_true : (n, 6) true injected fault, SI
    events : IMU-channel alarm events (all estimators)
    fault_windows : (start, end) of the scenario's faults, s
    duration_s : run length, s
    wall_s : wall time of simulation + monitor, s
    """

    name: str
    t_s: np.ndarray
    f_hat: dict[str, np.ndarray]
    f_true: np.ndarray
    events: list[AlarmEvent]
    fault_windows: list[tuple[float, float]]
    duration_s: float
    wall_s: float = 0.0
    extra: dict[str, Any] = field(default_factory=dict)
