"""``gcs-monitor calibrate``: a configuration for one's own airframe from its clean flights.

The defaults suit the simulated airframes; another airframe has other sensors and another
fault-free residual floor. From flights known to be fault-free this derives, in two passes:

1. **the sensor noise model** from the telemetry itself, with robust (median absolute deviation)
   estimators that motion does not inflate: IMU accelerometer and gyro noise from the first
   differences of each axis (``sigma = MAD(dx) / (0.6745 sqrt 2)``), GPS-velocity and attitude
   noise from second differences (``MAD(d2x) / (0.6745 sqrt 6)``), the AoA and CAS instances'
   noise from the differences between instances (``MAD(x_i - x_j) / (0.6745 sqrt 2)``). They
   become the Lu2016 / Atmaca2025 noise tables (R and Q of the IMU estimators, which set their
   gates) and the classifier's noise of every set;
2. **the thresholds** by replaying each flight with that noise model and detection switched off
   (every J_th raised out of reach, so nothing is isolated and the residuals stay those of a
   healthy vehicle): ``J_th = margin x`` the largest residual RMS J of any flight (Wan2018 sec.
   VI-B's rule: zero false alarms on the fault-free runs), per redundant set, per IMU
   estimator and sensor kind, and for the yaw-rate family's reconstructed gyro fault.

Between the two passes, when the flights carry what it needs (body rates, attitude, sideslip,
surface positions or commands, airspeed), the yaw-rate family's lateral-directional LPV model is
identified from them (Chen2020 eq. 59 by equation error,
:func:`~gcs_monitor.models.lateral.identify_lateral_model`) and its observer designed on it
(Chen2020 sec. III LMIs, :func:`~gcs_monitor.families.yaw_rate.design.design_observer`); the
design is written as JSON and the second pass already runs on it. A flight at one speed gives a
constant model valid only near the speeds flown: the family judges only inside that range
(``[yaw_rate.observer] eas_margin``). When an input is missing, the family keeps its shipped
design and the calibration says which input was missing.

It prints, per flight, the largest J against the new J_th (the margin each flight keeps) and
when it came, and writes a TOML file with only what it changed, which ``replay`` and ``live``
accept (``--config``). Flights: any log the monitor reads (``.tlog``, ArduPilot ``.bin``/``.log``,
PX4 ``.ulg``, the CSV layouts).

A flight that is not fault-free all through (a crash, a hard landing, a sensor that failed)
sets J_th from its worst moment and blinds the monitor: a real ArduCopter log of the data folder
crashes 51.6 s in (its own ``ERR`` record) and alone gives a gyro J_th of 65 deg/s. The largest
J of such a moment stands far above the rest of its flight, so each flight's largest J is
compared with its 95th percentile: beyond :data:`SPIKE_RATIO` times, ``calibrate`` says which
flight, key and time, and that the part can be left out. ``PATH@T0:T1`` calibrates on the
vehicle times T0..T1 s of a flight only (either bound may be left out: ``log.bin@60:``); the
whole flight is still replayed (the estimators need its history), only the samples outside are
not learnt from.
"""

from __future__ import annotations

import dataclasses
import json
import math
from array import array
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gcs_monitor.config import MonitorConfig
from gcs_monitor.config.loader import config_tables, toml_value
from gcs_monitor.families.yaw_rate.design import design_observer
from gcs_monitor.fdi.records import StepOutput
from gcs_monitor.link.logs import open_log
from gcs_monitor.models.lateral import LateralRecorder, LpvFitError, identify_lateral_model
from gcs_monitor.monitor import Monitor
from gcs_monitor.telemetry.frame import Frame

MAD_SIGMA = 0.6745  # MAD of a Gaussian / its sigma
OUT_OF_REACH = 1.0e9  # J_th that nothing reaches (detection off while observing)
# a flight's largest J beyond this many times its 95th percentile is a moment, not the flight's
# residual floor (module docstring): calibrate names it. On clean flights (the simulator's demo
# and Lu2016 turbulence flights, two Zipline launches, the OnSpeed stall run) the ratio is
# 1.0-2.0; on the two ArduCopter logs that end in or contain a crash the gyro's is 4.2 and 12.6
SPIKE_RATIO = 3.0
SPIKE_PERCENTILE = 95.0
IMU_SETS = ("ts", "hosm")
IMU_ESTIMATORS = {"imu_ts": "ts", "imu_ts_as": "ts", "imu_hosm": "hosm"}  # estimator -> section
YAW_RATE_ESTIMATOR = "yaw_rate_smo"


@dataclass
class _Noise:
    """Per-flight samples for the robust noise estimates (differences, SI)."""

    acc: list[np.ndarray] = field(default_factory=list)  # (n, 3) first differences
    gyro: list[np.ndarray] = field(default_factory=list)
    gps_vel: list[np.ndarray] = field(default_factory=list)  # (n, 3) second differences
    euler: list[np.ndarray] = field(default_factory=list)
    aoa_pair: list[np.ndarray] = field(default_factory=list)  # instance differences
    cas_pair: list[np.ndarray] = field(default_factory=list)


@dataclass(frozen=True)
class FlightPart:
    """A flight, or the part of it (vehicle time ``t0_s``..``t1_s``) calibrate learns from."""

    path: Path
    t0_s: float = -math.inf
    t1_s: float = math.inf

    @property
    def windowed(self) -> bool:
        return self.t0_s > -math.inf or self.t1_s < math.inf

    @property
    def name(self) -> str:
        if not self.windowed:
            return self.path.name
        lo = "" if self.t0_s == -math.inf else f"{self.t0_s:g}"
        hi = "" if self.t1_s == math.inf else f"{self.t1_s:g}"
        return f"{self.path.name}@{lo}:{hi}"

    def covers(self, t_us: int) -> bool:
        return self.t0_s <= t_us * 1e-6 <= self.t1_s


def parse_flight(text: str | Path) -> FlightPart:
    """``PATH`` or ``PATH@T0:T1`` (vehicle time, s; either bound may be left out).

    Raises
    ------
    ValueError
        on a window that is not two numbers with T0 < T1
    """
    text = str(text)
    path, at, window = text.rpartition("@")
    if not at or Path(text).exists():
        return FlightPart(Path(text))
    lo, colon, hi = window.partition(":")
    try:
        if not colon:
            raise ValueError
        t0 = float(lo) if lo.strip() else -math.inf
        t1 = float(hi) if hi.strip() else math.inf
    except ValueError:
        raise ValueError(f"{text}: expected PATH@T0:T1 (vehicle time in s, e.g. "
                         f"{path}@60:190 or {path}@:190)") from None
    if not t0 < t1:
        raise ValueError(f"{text}: the window's start {t0:g} s is not before its end {t1:g} s")
    return FlightPart(Path(path), t0, t1)


@dataclass
class FlightStats:
    """What one flight contributed."""

    name: str
    duration_s: float
    j_max: dict[str, float] = field(default_factory=dict)  # key -> largest J (SI)
    j_at_s: dict[str, float] = field(default_factory=dict)  # key -> vehicle time of it (s)
    j_p95: dict[str, float] = field(default_factory=dict)  # key -> 95th percentile of J

    def spikes(self) -> dict[str, float]:
        """Keys whose largest J is an isolated moment (> SPIKE_RATIO x the flight's
        SPIKE_PERCENTILE-th percentile): key -> that ratio."""
        return {k: j / self.j_p95[k] for k, j in self.j_max.items()
                if self.j_p95.get(k, 0.0) > 0.0 and j > SPIKE_RATIO * self.j_p95[k]}


@dataclass(frozen=True)
class YawRateModel:
    """The yaw-rate family's lateral model identified from the flights, or why there is none.

    design_path : the written design (JSON), None when the family keeps its shipped design
    fit : the identification's fit error (derivative NRMSE per state), None when not identified
    eas_range_mps : the equivalent airspeeds the model was identified on (m/s)
    constant : the speeds flown spanned too little to fit the speed terms (A_1 = A_2 = 0)
    gamma : L2-gain bound of each sensor's observer (Chen2020 sec. IV condition)
    reason : why not identified (the missing input, too few samples, the LMI failing)
    """

    design_path: Path | None = None
    fit: LpvFitError | None = None
    eas_range_mps: tuple[float, float] | None = None
    constant: bool = False
    gamma: dict[str, float] = field(default_factory=dict)
    reason: str = ""

    def summary(self, kept: str, eas_margin: float) -> list[str]:
        """What ``calibrate`` prints about the yaw-rate family (``kept``: the configured design,
        kept when none was identified; ``eas_margin``: ``[yaw_rate.observer] eas_margin``, the
        share outside the model's speeds the family still judges)."""
        if self.design_path is None or self.fit is None or self.eas_range_mps is None:
            what = "configured" if kept.endswith(".json") else "shipped"
            return [f"yaw_rate: lateral model NOT identified: {self.reason}; the family keeps "
                    f"its {what} design {kept!r}"]
        lo, hi = self.eas_range_mps
        nr = ", ".join(f"{k} {v:.3g}" for k, v in zip(("phi", "beta", "p", "r"), self.fit.nrmse,
                                                         strict=True))
        valid = (f"flown at one speed (EAS {lo:.1f}-{hi:.1f} m/s): a constant model, valid only "
                 f"near that speed" if self.constant else
                 f"scheduled on EAS over {lo:.1f}-{hi:.1f} m/s")
        gam = ", ".join(f"{k} {v:.4g}" for k, v in sorted(self.gamma.items()))
        return [f"yaw_rate: lateral model identified from {self.fit.n_points} samples, {valid}; "
                f"the family judges only at EAS {lo * (1.0 - eas_margin):.1f}-"
                f"{hi * (1.0 + eas_margin):.1f} m/s ([yaw_rate.observer] eas_margin "
                f"{100.0 * eas_margin:g} %)",
                f"yaw_rate: fit error (derivative NRMSE): {nr}",
                f"yaw_rate: observer L2-gain bounds: {gam}; design -> {self.design_path}"]


@dataclass
class Calibration:
    """The calibrated configuration and how it was reached."""

    config: MonitorConfig
    noise: dict[str, float]  # noise sigma per signal, SI
    thresholds: dict[str, float]  # J_th per key, SI
    flights: list[FlightStats]
    margin: float
    yaw_rate: YawRateModel = field(default_factory=YawRateModel)


def flight_chunks(path: Path) -> Iterator[tuple[bytes, float]]:
    """MAVLink bytes of a flight in any format the monitor reads (``.tlog``, ArduPilot
    ``.bin``/``.log``, PX4 ``.ulg``, the CSV layouts; :func:`gcs_monitor.link.logs.open_log`)."""
    with open_log(path).source as src:
        yield from src


def _mad_sigma(parts: Sequence[np.ndarray], scale: float) -> float:
    """Robust sigma of the pooled differences (``MAD / 0.6745 / scale``), NaN without data."""
    if not parts:
        return math.nan
    x = np.concatenate([np.ravel(p) for p in parts])
    x = x[np.isfinite(x)]
    if x.size < 20:
        return math.nan
    return float(np.median(np.abs(x - np.median(x))) / MAD_SIGMA / scale)


class _NoiseRecorder:
    """Collects the primary IMU, GPS velocity, attitude and air data of one flight, and the
    lateral signals of every flight (``lateral``, shared)."""

    def __init__(self, lateral: LateralRecorder) -> None:
        self.lateral = lateral
        self.imu: list[np.ndarray] = []
        self.att: list[np.ndarray] = []
        self.gps: list[np.ndarray] = []
        self.aoa: list[np.ndarray] = []
        self.cas: list[np.ndarray] = []

    def __call__(self, sysid: int, frame: Frame, out: StepOutput) -> None:
        self.lateral.add(frame)
        imu = frame.primary_imu
        if imu is not None and imu.t_us == frame.t_us:
            self.imu.append(np.concatenate([imu.acc_frd_mps2, imu.omega_frd_radps]))
        if frame.euler_rad is not None and frame.att_age_s == 0.0:
            self.att.append(np.asarray(frame.euler_rad, dtype=float))
        if frame.gps_new and frame.gps_vel_ned_mps is not None:
            self.gps.append(np.asarray(frame.gps_vel_ned_mps, dtype=float))
        if frame.air_new:
            self.aoa.append(np.asarray(frame.aoa_rad, dtype=float))
            self.cas.append(np.asarray(frame.cas_mps, dtype=float))

    def into(self, n: _Noise) -> None:
        if len(self.imu) > 3:
            d = np.diff(np.array(self.imu), axis=0)
            n.acc.append(d[:, :3])
            n.gyro.append(d[:, 3:])
        if len(self.gps) > 3:
            n.gps_vel.append(np.diff(np.array(self.gps), n=2, axis=0))
        if len(self.att) > 3:
            a = np.unwrap(np.array(self.att), axis=0)
            n.euler.append(np.diff(a, n=2, axis=0))
        for vals, dest in ((self.aoa, n.aoa_pair), (self.cas, n.cas_pair)):
            if len(vals) > 3:
                v = np.array(vals)
                for i in range(v.shape[1]):
                    for j in range(i + 1, v.shape[1]):
                        dest.append(v[:, i] - v[:, j])


def _replay(path: Path, cfg: MonitorConfig,
            on_step: Callable[[int, Frame, StepOutput], None]) -> float:
    """Replay one flight through ``cfg``; its duration (vehicle s)."""
    mon = Monitor(cfg, on_step=on_step)
    for data, wall in flight_chunks(path):
        mon.feed(data, wall)
    mon.finish()
    return max((v.last_t_us for v in mon.vehicles.values()), default=0) * 1e-6


def with_noise(cfg: MonitorConfig, noise: dict[str, float]) -> MonitorConfig:
    """``cfg`` with the measured noise in the estimators' and classifier's tables (only the
    signals that were measured)."""
    def have(k: str) -> bool:
        return math.isfinite(noise.get(k, math.nan)) and noise[k] > 0.0

    imu = cfg.family("imu")
    ts_n = imu.ts.estimator.noise
    ts_n = dataclasses.replace(
        ts_n, **{f: noise[k] for f, k in (("acc_sigma_mps2", "acc"), ("gyro_sigma_radps", "gyro"),
                                          ("vel_sigma_mps", "gps_vel"),
                                          ("euler_sigma_rad", "euler")) if have(k)})
    h_n = imu.hosm.estimator.noise
    h_n = dataclasses.replace(
        h_n, **{f: noise[k] for f, k in (("acc_sigma_mps2", "acc"), ("gyro_sigma_radps", "gyro"),
                                         ("gps_vel_sigma_mps", "gps_vel"),
                                         ("phi_theta_sigma_rad", "euler"),
                                         ("psi_sigma_rad", "euler")) if have(k)})
    imu = dataclasses.replace(
        imu,
        ts=dataclasses.replace(imu.ts, estimator=dataclasses.replace(imu.ts.estimator,
                                                                     noise=ts_n)),
        hosm=dataclasses.replace(imu.hosm, estimator=dataclasses.replace(imu.hosm.estimator,
                                                                         noise=h_n)))
    air = cfg.family("airdata")
    fdi = air.fdi
    for s in ("aoa", "cas"):
        if have(s):
            fdi = dataclasses.replace(fdi, **{s: dataclasses.replace(getattr(fdi, s),
                                                                     noise_sigma=noise[s])})
    air = dataclasses.replace(air, fdi=fdi)
    return cfg.with_family("imu", imu).with_family("airdata", air)


def _observing(cfg: MonitorConfig) -> MonitorConfig:
    """``cfg`` with every J_th out of reach (nothing isolated while the J are recorded)."""
    imu = cfg.family("imu")
    sec = {}
    for name in IMU_SETS:
        s = getattr(imu, name)
        fdi = dataclasses.replace(s.fdi, acc=dataclasses.replace(s.fdi.acc, threshold=OUT_OF_REACH),
                                  gyro=dataclasses.replace(s.fdi.gyro, threshold=OUT_OF_REACH))
        sec[name] = dataclasses.replace(s, fdi=fdi)
    air = cfg.family("airdata")
    fdi = dataclasses.replace(
        air.fdi, aoa=dataclasses.replace(air.fdi.aoa, threshold=OUT_OF_REACH),
        cas=dataclasses.replace(air.fdi.cas, threshold=OUT_OF_REACH))
    yaw = cfg.family("yaw_rate")
    return (cfg.with_family("imu", dataclasses.replace(imu, **sec))
            .with_family("airdata", dataclasses.replace(air, fdi=fdi))
            .with_family("yaw_rate", fdi=dataclasses.replace(yaw.fdi, threshold=OUT_OF_REACH)))


class _JRecorder:
    """The residual RMS per set and per IMU estimator and kind: per frame the largest over the
    key's channels, with the frame's vehicle time."""

    def __init__(self) -> None:
        # key -> (t_s, J), packed doubles: a flight of an hour at 100 Hz is 360k frames per key
        self.series: dict[str, tuple[array[float], array[float]]] = {}
        self._frame: dict[str, float] = {}

    def _put(self, key: str, j: float) -> None:
        if math.isfinite(j) and j > self._frame.get(key, -1.0):
            self._frame[key] = j

    def __call__(self, sysid: int, frame: Frame, out: StepOutput) -> None:
        for s in out.sets:
            for j in s.rms:
                self._put(f"airdata.{s.name}", j)
        for c in out.channels:
            if c.rms <= 0.0:  # 0 until the channel is judged (estimator warm-up)
                continue
            if c.estimator == YAW_RATE_ESTIMATOR:
                self._put(f"yaw_rate.{c.channel.axis}", c.rms)
            elif c.estimator in IMU_ESTIMATORS:
                self._put(f"imu.{IMU_ESTIMATORS[c.estimator]}.{c.channel.kind}", c.rms)
        for key, j in self._frame.items():
            ts, js = self.series.setdefault(key, (array("d"), array("d")))
            ts.append(frame.t_us * 1e-6)
            js.append(j)
        self._frame.clear()

    def into(self, st: FlightStats) -> None:
        """The flight's largest J per key, its vehicle time and the SPIKE_PERCENTILE-th
        percentile of J into ``st``."""
        for key, (ts, js) in self.series.items():
            j = np.frombuffer(js, dtype=np.float64)
            k = int(np.argmax(j))  # the first of equal maxima
            st.j_max[key], st.j_at_s[key] = js[k], ts[k]
            st.j_p95[key] = float(np.percentile(j, SPIKE_PERCENTILE))


def identify_yaw_rate(lateral: LateralRecorder, design_path: Path, *,
                      command: str = "") -> YawRateModel:
    """The yaw-rate family's lateral model and observer from the recorded flights, written to
    ``design_path``; or, when the flights cannot give one, the reason (nothing written).

    The model is Chen2020 eq. 59 by equation error
    (:func:`~gcs_monitor.models.lateral.identify_lateral_model`), the observer gains those of
    Chen2020 sec. III-IV (:func:`~gcs_monitor.families.yaw_rate.design.design_observer`, which
    needs cvxpy: the ``design`` extra).
    """
    missing = lateral.missing()
    if lateral.frames == 0:
        return YawRateModel(reason="the flights gave no telemetry frame")
    if missing:
        return YawRateModel(reason="the flights carry no " + ", no ".join(missing))
    try:
        model, fit = identify_lateral_model(lateral.samples(), source=command)
    except ValueError as exc:  # every input sent, but never together or too briefly
        return YawRateModel(reason=str(exc))
    try:
        design = design_observer(model, fit=fit, command=command)
    except ImportError as exc:
        return YawRateModel(fit=fit, reason=f"the LMI design needs cvxpy (pip install "
                            f"'gcs-monitor[design]'): {exc}")
    except RuntimeError as exc:  # the LMIs infeasible on the identified model
        return YawRateModel(fit=fit, reason=str(exc))
    design_path.parent.mkdir(parents=True, exist_ok=True)
    design_path.write_text(json.dumps(design.to_dict(), indent=1) + "\n")
    constant = not (np.any(model.A[1:]) or np.any(model.B[1:]))
    return YawRateModel(design_path, fit, model.eas_range_mps, constant,
                        {k: float(v["gamma"]) for k, v in design.meta["lmi"].items()})


def _within(part: FlightPart, rec: Callable[[int, Frame, StepOutput], None]
            ) -> Callable[[int, Frame, StepOutput], None]:
    """``rec`` for the frames of ``part``'s window only."""
    if not part.windowed:
        return rec

    def step(sysid: int, frame: Frame, out: StepOutput) -> None:
        if part.covers(frame.t_us):
            rec(sysid, frame, out)
    return step


def calibrate(flights: Sequence[Path | FlightPart], base: MonitorConfig | None = None, *,
              margin: float = 1.5, design_path: Path | None = None,
              progress: Callable[[str], None] = lambda s: None) -> Calibration:
    """Noise model and thresholds from fault-free ``flights`` (module docstring), each a path
    or a :class:`FlightPart` (learn from a window of it only).

    ``design_path``: where to write the yaw-rate family's identified design (JSON); None: the
    lateral model is not identified and the family keeps the design of ``base``.
    """
    if not flights:
        raise ValueError("calibrate needs at least one flight")
    parts = [f if isinstance(f, FlightPart) else FlightPart(Path(f)) for f in flights]
    if not margin > 1.0:
        raise ValueError(f"margin must be > 1, got {margin}")
    cfg = base if base is not None else MonitorConfig()
    samples = _Noise()
    stats: list[FlightStats] = []
    lateral = LateralRecorder()
    for i, part in enumerate(parts):
        progress(f"[1/2] noise {i + 1}/{len(parts)}: {part.name}")
        rec = _NoiseRecorder(lateral)
        dur = _replay(part.path, _observing(cfg), _within(part, rec))
        rec.into(samples)
        stats.append(FlightStats(part.name, dur))
    noise = {
        "acc": _mad_sigma(samples.acc, math.sqrt(2.0)),
        "gyro": _mad_sigma(samples.gyro, math.sqrt(2.0)),
        "gps_vel": _mad_sigma(samples.gps_vel, math.sqrt(6.0)),
        "euler": _mad_sigma(samples.euler, math.sqrt(6.0)),
        "aoa": _mad_sigma(samples.aoa_pair, math.sqrt(2.0)),
        "cas": _mad_sigma(samples.cas_pair, math.sqrt(2.0)),
    }
    noisy = with_noise(cfg, noise)
    yaw = YawRateModel(reason="no design path given")
    if not cfg.family("yaw_rate").enabled:
        yaw = YawRateModel(reason="the yaw-rate family is disabled in the configuration")
    elif design_path is not None:
        progress("[1/2] yaw-rate lateral model and observer design")
        yaw = identify_yaw_rate(lateral, design_path, command="gcs-monitor calibrate "
                                + " ".join(p.name for p in parts))
        if yaw.design_path is not None:  # absolute: replay and live run from anywhere
            noisy = noisy.with_family("yaw_rate", design=str(yaw.design_path.resolve()))
    observe = _observing(noisy)
    for i, part in enumerate(parts):
        progress(f"[2/2] residuals {i + 1}/{len(parts)}: {part.name}")
        jr = _JRecorder()
        _replay(part.path, observe, _within(part, jr))
        jr.into(stats[i])
    j_all: dict[str, float] = {}
    for st in stats:
        for k, v in st.j_max.items():
            j_all[k] = max(j_all.get(k, 0.0), v)
    thresholds = {k: margin * v for k, v in j_all.items() if v > 0.0}
    return Calibration(_with_thresholds(noisy, thresholds), noise, thresholds, stats, margin,
                       yaw)


def _with_thresholds(cfg: MonitorConfig, th: dict[str, float]) -> MonitorConfig:
    imu = cfg.family("imu")
    sec: dict[str, Any] = {}
    for name in IMU_SETS:
        s = getattr(imu, name)
        fdi = s.fdi
        for kind in ("acc", "gyro"):
            v = th.get(f"imu.{name}.{kind}")
            if v is not None:
                fdi = dataclasses.replace(fdi, **{kind: dataclasses.replace(getattr(fdi, kind),
                                                                            threshold=v)})
        sec[name] = dataclasses.replace(s, fdi=fdi)
    air = cfg.family("airdata")
    fdi = air.fdi
    for s in ("aoa", "cas"):
        v = th.get(f"airdata.{s}")
        if v is not None:
            fdi = dataclasses.replace(fdi, **{s: dataclasses.replace(getattr(fdi, s), threshold=v)})
    cfg = (cfg.with_family("imu", dataclasses.replace(imu, **sec))
           .with_family("airdata", dataclasses.replace(air, fdi=fdi)))
    yaw = cfg.family("yaw_rate")
    v = th.get(f"yaw_rate.{yaw.sensor}")
    if v is not None:
        cfg = cfg.with_family("yaw_rate", fdi=dataclasses.replace(yaw.fdi, threshold=v))
    return cfg


def calibration_toml(cal: Calibration, base: MonitorConfig,
                     flights: Sequence[Path | FlightPart]) -> str:
    """The calibrated configuration as TOML: only the keys it changed against ``base``, with a
    header saying where they came from (``load_config(path, base=...)`` restores the rest)."""
    lines = [f"# gcs-monitor calibrate on {len(flights)} fault-free flight(s), margin "
             f"{cal.margin:g} x the largest residual RMS of any flight:",
             *(f"#   {p.name}" for p in flights),
             "# Use with --config; every other key keeps its default (gcs-monitor config "
             "--defaults)."]
    old = {(t.name, e.key): e.value for t in config_tables(base) for e in t.entries}
    for t in config_tables(cal.config):
        changed = [e for e in t.entries if old.get((t.name, e.key)) != e.value]
        if changed:
            lines += ["", f"[{t.name}]"]
            lines += [f"{e.key} = {toml_value(e.value)}  # {e.doc}" for e in changed]
    return "\n".join(lines) + "\n"


def margins_table(cal: Calibration) -> list[str]:
    """Per flight and key: the largest J as a share of the new J_th (the margin kept), its
    vehicle time, and the flight's 95th percentile of J as a share of J_th (its floor)."""
    keys = sorted(cal.thresholds)
    lines = ["| flight | duration s | " + " | ".join(keys) + " |",
             "|---|---|" + "---|" * len(keys)]
    for st in cal.flights:
        cells = []
        for k in keys:
            j = st.j_max.get(k)
            at = st.j_at_s.get(k)
            p95 = st.j_p95.get(k)
            cells.append("-" if j is None else f"{j / cal.thresholds[k]:.2f}"
                         + ("" if at is None else f" at {at:.1f} s")
                         + ("" if p95 is None else f" (p95 {p95 / cal.thresholds[k]:.2f})"))
        lines.append(f"| {st.name} | {st.duration_s:.0f} | " + " | ".join(cells) + " |")
    return lines


def spike_warnings(cal: Calibration) -> list[str]:
    """What ``calibrate`` says about flights whose largest J is one moment far above the rest of
    the flight (:meth:`FlightStats.spikes`): the flight, the key, when, and what it did to the
    threshold; empty when there is none."""
    out = []
    for st in cal.flights:
        for key, ratio in sorted(st.spikes().items()):
            th = cal.thresholds.get(key)
            sets = th is not None and st.j_max[key] * cal.margin >= th
            out.append(
                f"warning: {st.name}: the largest {key} J ({st.j_max[key]:.4g}, at "
                f"{st.j_at_s[key]:.1f} s) is {ratio:.1f} x the flight's "
                f"{SPIKE_PERCENTILE:g}th percentile ({st.j_p95[key]:.4g})"
                + (": it sets that J_th" if sets else "")
                + ". A crash, a hard landing or a failing sensor there makes the threshold "
                "blind to faults; if the flight was not fault-free at that moment, calibrate "
                "on the rest of it (FLIGHT@T0:T1, vehicle time in s)")
    return out
