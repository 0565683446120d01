"""Strict TOML loading into frozen dataclasses.

Keys carry their unit (``threshold_deg``, ``gps_delay_s``); values are converted to SI here, once.
Unknown keys, wrong types and out-of-range values stop with a message naming the file and key.
"""

from __future__ import annotations

import dataclasses
import tomllib
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from gcs_monitor.core.units import DEG2RAD, KT2MPS
from gcs_monitor.models.airdata import WindEnvelope

_ENV = WindEnvelope()


class ConfigError(ValueError):
    """Invalid monitor configuration; the message names the file, the key and what is expected."""


@dataclass(frozen=True, slots=True)
class TelemetryConfig:
    gps_delay_s: float = 0.1  # interpolation delay D (one GPS period at 10 Hz), Lu2016 sec. 5
    stale_after_s: float = 0.5  # an input older than this is invalid
    primary_imu: int = 0


@dataclass(frozen=True, slots=True)
class SetConfig:
    """One redundant set's FDI parameters (Wan2018 sec. III-A)."""

    threshold: float  # J_th, SI
    n_eval: int = 10  # N_eval, Wan2018
    n_detect: int = 5  # n_D of the last N_eval samples over threshold
    clear_ratio: float = 0.5
    n_clear: int = 200
    latch: bool = True
    # frozen-signal (jam) check of a redundant set, window in s; 0 turns it off
    # (gcs_monitor.fdi.monitor.FrozenSignalCheck; used by the AoA and CAS sets)
    stuck_window_s: float = 0.5
    # J_th grows with the declared turbulence: J_th = threshold + threshold_per_turbulence *
    # airdata.turbulence_sigma_mps (SI per m/s of Dryden sigma; 0 = one fixed J_th as Wan2018).
    # TOML: threshold_slope_deg_per_mps (aoa), threshold_slope_kts_per_mps (cas).
    threshold_per_turbulence: float = 0.0
    # no-data check: an instance without a valid value for this long while a peer delivers is
    # isolated (fault type no_data); 0 turns it off (AoA and CAS sets). It counts after the
    # telemetry's stale_after_s has made the instance invalid.
    no_data_window_s: float = 0.5
    # restart the healthy peers' residual windows when an instance is isolated (ours, not
    # Wan2018; gcs_monitor.fdi.monitor.SetMonitorParams.restart_peers); false = Wan2018's scheme
    restart_peers: bool = True
    # with two healthy instances left, fuse them with equal eq. 19 weights while both are
    # below J_th (ours, not Wan2018; gcs_monitor.pipeline.MheMeasurementFusion); off by default
    equal_pair_weights: bool = False


def scheduled_threshold(cfg: SetConfig, turbulence_sigma_mps: float) -> float:
    """J_th of a set for the declared Dryden intensity (SI): the fault-free residual floor of
    the air-data sets grows with the gusts the one-step prediction cannot foresee."""
    return cfg.threshold + cfg.threshold_per_turbulence * turbulence_sigma_mps


HOSM_ACC_MPS2 = 0.64  # imu_hosm thresholds (FdiConfig.acc_hosm, gyro_hosm), see there
HOSM_GYRO_DEGPS = 0.25


@dataclass(frozen=True, slots=True)
class FdiConfig:
    aoa: SetConfig = field(default_factory=lambda: SetConfig(threshold=1.0 * DEG2RAD))
    cas: SetConfig = field(default_factory=lambda: SetConfig(threshold=4.0 * KT2MPS))
    # IMU fault-estimate thresholds: 1.5 x the worst fault-free RMS of the ATSEKF fault
    # estimates over fault-free runs of every manoeuvre in turbulence (calibration seeds, not the
    # evaluation seeds): `gcs-monitor evaluate --experiment imu_detection` prints them.
    acc: SetConfig = field(default_factory=lambda: SetConfig(threshold=0.19, n_eval=50,
                                                             n_detect=40, latch=False))
    gyro: SetConfig = field(default_factory=lambda: SetConfig(threshold=0.35 * DEG2RAD,
                                                              n_eval=50, n_detect=40,
                                                              latch=False))
    # The same for the OTSEKF+HOSM fault estimates (Atmaca2025, estimator imu_hosm), calibrated
    # the same way on its own fault-free runs (same calibration seeds 101, 102, not the
    # evaluation seeds): `gcs-monitor evaluate --experiment imu_detection_hosm` prints them
    # (acc 0.6345 m/s^2, gyro 0.2411 deg/s with the exact drift-to-fault map of Atmaca2025
    # eq. 51; docs/results.md, "Detection and isolation with imu_hosm"). Defaults rounded up.
    acc_hosm: SetConfig = field(default_factory=lambda: SetConfig(threshold=HOSM_ACC_MPS2,
                                                                  n_eval=50, n_detect=40,
                                                                  latch=False))
    gyro_hosm: SetConfig = field(default_factory=lambda: SetConfig(
        threshold=HOSM_GYRO_DEGPS * DEG2RAD, n_eval=50, n_detect=40, latch=False))


@dataclass(frozen=True, slots=True)
class EstimatorsConfig:
    imu_ts: bool = True
    imu_hosm: bool = False
    airdata: str = "cmhe"  # "cmhe" | "umhe" | "ekf" | "none"


@dataclass(frozen=True, slots=True)
class AirDataConfig:
    """The declared weather of the flight, from which the CMHE takes its wind bounds (SI).

    Wan2018 eq. 21b, sec. VI-A: the wind bounds "need to be properly selected according to the
    weather and flight conditions". This is that condition, declared like a forecast (TOML
    section ``[airdata]``, keys in knots: ``wind_kts``, ``wind_z_kts``, ``shear_kts``,
    ``shear_z_kts``, ``shear_rate_ktsps``, ``turbulence_sigma_kts``, plus
    ``turbulence_scale_m``, ``n_sigma``, ``flight_path_max_deg``, ``model_margin_kts``,
    ``model_rate_margin_ktsps``; ``lateral_terms`` (default true) adds bank and sideslip to
    eqs. 12-15;
    ``wind_accel_in_alpha`` switches the model between eq. 8's
    wind-acceleration term and Wan2018 eq. 13). The estimator turns it into bounds at every sample
    (``gcs_monitor.models.airdata.envelope_bounds``). Defaults: 18 m/s wind, 3 m/s vertical
    wind, 1.5 m/s^2 wind acceleration, no turbulence declared; with the model margins this
    gives about the fixed box the CMHE used before the envelope existed (|W_x| <= 21-22 m/s,
    |W_z| <= 8 m/s, |u_w| <= 2 m/s^2 wings level, against 20, 8, 2). One config file per flight
    condition (configs/weather_*.toml).
    """

    # the envelope's defaults live in one place: gcs_monitor.models.airdata.WindEnvelope
    wind_mps: float = _ENV.wind_mps
    wind_z_mps: float = _ENV.wind_z_mps
    shear_mps: float = _ENV.shear_mps
    shear_z_mps: float = _ENV.shear_z_mps
    shear_rate_mps2: float = _ENV.shear_rate_mps2
    turbulence_sigma_mps: float = _ENV.turbulence_sigma_mps
    turbulence_scale_m: float = _ENV.turbulence_scale_m  # Dryden L (Lu2016 sec. 2.2.1)
    n_sigma: float = _ENV.n_sigma
    flight_path_max_rad: float = _ENV.flight_path_max_rad
    model_margin_mps: float = _ENV.model_margin_mps
    model_rate_margin_mps2: float = _ENV.model_rate_margin_mps2
    wind_accel_in_alpha: bool = True  # eq. 8 term in the model (False: Wan2018 eq. 13)
    # bank and sideslip in eqs. 12-15 (models.airdata.lateral; ours). On by default: with the
    # wings-level forms a calm 31 deg-bank s-turn gives 1.2 deg of fault-free AoA J, above the
    # campaign's J_th (docs/results.md, "Wan2018's scheme"). False: Wan2018's forms exactly, as
    # the paper reproductions (evaluation.wan2018.variant_config) use them.
    lateral_terms: bool = True


# TOML key -> (field, factor to SI)
_AIRDATA_KEYS = {
    "wind_kts": ("wind_mps", KT2MPS),
    "wind_z_kts": ("wind_z_mps", KT2MPS),
    "shear_kts": ("shear_mps", KT2MPS),
    "shear_z_kts": ("shear_z_mps", KT2MPS),
    "shear_rate_ktsps": ("shear_rate_mps2", KT2MPS),
    "turbulence_sigma_kts": ("turbulence_sigma_mps", KT2MPS),
    "turbulence_scale_m": ("turbulence_scale_m", 1.0),
    "n_sigma": ("n_sigma", 1.0),
    "flight_path_max_deg": ("flight_path_max_rad", DEG2RAD),
    "model_margin_kts": ("model_margin_mps", KT2MPS),
    "model_rate_margin_ktsps": ("model_rate_margin_mps2", KT2MPS),
}


_AIRDATA_BOOLS = ("wind_accel_in_alpha", "lateral_terms")


def _airdata_config(data: Any, src: str) -> AirDataConfig:
    if not isinstance(data, dict):
        raise ConfigError(f"{src}: [airdata] must be a table")
    kwargs: dict[str, Any] = {}
    for key, value in data.items():
        if key in _AIRDATA_BOOLS:
            if not isinstance(value, bool):
                raise ConfigError(f"{src}: 'airdata.{key}' must be true or false, got {value!r}")
            kwargs[key] = value
            continue
        if key not in _AIRDATA_KEYS:
            raise ConfigError(f"{src}: unknown key 'airdata.{key}'; expected one of "
                              f"{sorted([*_AIRDATA_KEYS, *_AIRDATA_BOOLS])}")
        if isinstance(value, bool) or not isinstance(value, int | float) or value < 0:
            raise ConfigError(f"{src}: 'airdata.{key}' must be a non-negative number, got "
                              f"{value!r}")
        name, factor = _AIRDATA_KEYS[key]
        kwargs[name] = float(value) * factor
    cfg = AirDataConfig(**kwargs)
    if cfg.turbulence_scale_m <= 0.0:
        raise ConfigError(f"{src}: 'airdata.turbulence_scale_m' must be positive")
    return cfg


@dataclass(frozen=True, slots=True)
class SinksConfig:
    rerun_rate_hz: float = 20.0
    zenoh: bool = False
    zenoh_listen: tuple[str, ...] = ("tcp/127.0.0.1:7447",)
    zenoh_connect: tuple[str, ...] = ()
    estimate_rate_hz: float = 5.0
    queue_size: int = 10_000


@dataclass(frozen=True, slots=True)
class MonitorConfig:
    telemetry: TelemetryConfig = field(default_factory=TelemetryConfig)
    fdi: FdiConfig = field(default_factory=FdiConfig)
    estimators: EstimatorsConfig = field(default_factory=EstimatorsConfig)
    sinks: SinksConfig = field(default_factory=SinksConfig)
    airdata: AirDataConfig = field(default_factory=AirDataConfig)


_UNIT_TO_SI = {"deg": DEG2RAD, "kts": KT2MPS, "mps2": 1.0, "degps": DEG2RAD}  # threshold keys
_SET_UNITS = {"aoa": "deg", "cas": "kts", "acc": "mps2", "gyro": "degps",
              "acc_hosm": "mps2", "gyro_hosm": "degps"}
_AIRDATA = ("cmhe", "umhe", "ekf", "none")


def _build(cls: type, data: dict[str, Any], where: str, src: str) -> Any:
    if not isinstance(data, dict):
        raise ConfigError(f"{src}: [{where}] must be a table")
    hints = typing.get_type_hints(cls)
    names = {f.name for f in dataclasses.fields(cls)}
    kwargs: dict[str, Any] = {}
    for key, value in data.items():
        if key not in names:
            raise ConfigError(f"{src}: unknown key '{where}.{key}'; expected one of "
                              f"{sorted(names)}")
        kwargs[key] = _coerce(hints[key], value, f"{where}.{key}", src)
    return cls(**kwargs)


def _coerce(tp: Any, value: Any, key: str, src: str) -> Any:
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if args and type(None) in args and origin is not tuple:  # X | None
        (inner,) = [a for a in args if a is not type(None)]
        return _coerce(inner, value, key, src)
    if tp is bool:
        if not isinstance(value, bool):
            raise ConfigError(f"{src}: '{key}' must be true or false, got {value!r}")
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int) or value <= 0:
            raise ConfigError(f"{src}: '{key}' must be a positive integer, got {value!r}")
        return value
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, int | float) or value < 0:
            raise ConfigError(f"{src}: '{key}' must be a non-negative number, got {value!r}")
        return float(value)
    if tp is str:
        if not isinstance(value, str):
            raise ConfigError(f"{src}: '{key}' must be a string, got {value!r}")
        return value
    if origin is tuple:
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            raise ConfigError(f"{src}: '{key}' must be a list of strings, got {value!r}")
        return tuple(value)
    raise ConfigError(f"{src}: '{key}' has an unsupported type")


def _set_config(name: str, data: dict[str, Any], src: str) -> SetConfig:
    if not isinstance(data, dict):
        raise ConfigError(f"{src}: [fdi.{name}] must be a table")
    unit = _SET_UNITS[name]
    thr_key = f"threshold_{unit}"
    data = dict(data)
    slope_key = f"threshold_slope_{unit}_per_mps"
    for k in list(data):
        if k.startswith("threshold") and k not in (thr_key, slope_key):
            raise ConfigError(f"{src}: '{k}' in [fdi.{name}]: the threshold of this set is given "
                              f"as '{thr_key}' (and its growth with the declared turbulence as "
                              f"'{slope_key}')")
    default: SetConfig = getattr(FdiConfig(), name)
    threshold = default.threshold
    if thr_key in data:
        raw = data.pop(thr_key)
        if isinstance(raw, bool) or not isinstance(raw, int | float) or raw <= 0:
            raise ConfigError(f"{src}: 'fdi.{name}.{thr_key}' must be a positive number")
        threshold = float(raw) * _UNIT_TO_SI[unit]
    slope = default.threshold_per_turbulence
    if slope_key in data:
        raw = data.pop(slope_key)
        if isinstance(raw, bool) or not isinstance(raw, int | float) or raw < 0:
            raise ConfigError(f"{src}: 'fdi.{name}.{slope_key}' must be a non-negative number")
        slope = float(raw) * _UNIT_TO_SI[unit]
    partial = _build(_SetPartial, data, f"fdi.{name}", src)
    given = {f.name: getattr(partial, f.name) for f in dataclasses.fields(_SetPartial)
             if getattr(partial, f.name) is not None}
    cfg = dataclasses.replace(default, threshold=threshold, threshold_per_turbulence=slope,
                              **given)
    if cfg.no_data_window_s < 0.0:
        raise ConfigError(f"{src}: 'fdi.{name}.no_data_window_s' must be 0 (off) or positive, "
                          f"got {cfg.no_data_window_s}")
    if 0.0 < cfg.stuck_window_s < 0.5:
        raise ConfigError(f"{src}: 'fdi.{name}.stuck_window_s' must be 0 (off) or at least "
                          f"0.5 s, got {cfg.stuck_window_s}")
    if cfg.n_detect > cfg.n_eval:
        raise ConfigError(f"{src}: 'fdi.{name}.n_detect' ({cfg.n_detect}) must not exceed "
                          f"n_eval ({cfg.n_eval})")
    return cfg


@dataclass(frozen=True, slots=True)
class _SetPartial:
    """The keys of one [fdi.<set>] table besides its threshold; None = not given (default)."""

    n_eval: int | None = None
    n_detect: int | None = None
    clear_ratio: float | None = None
    n_clear: int | None = None
    latch: bool | None = None
    stuck_window_s: float | None = None
    no_data_window_s: float | None = None
    restart_peers: bool | None = None
    equal_pair_weights: bool | None = None


def load_config(path: Path | None = None) -> MonitorConfig:
    """Load a monitor TOML file; ``None`` gives the defaults (the simulated airframes)."""
    if path is None:
        return MonitorConfig()
    src = str(path)
    try:
        with open(path, "rb") as fh:
            data = tomllib.load(fh)
    except FileNotFoundError:
        raise ConfigError(f"{src}: no such config file") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{src}: not valid TOML: {exc}") from None
    allowed = {"telemetry", "fdi", "estimators", "sinks", "airdata"}
    for key in data:
        if key not in allowed:
            raise ConfigError(f"{src}: unknown section [{key}]; expected one of {sorted(allowed)}")
    tel = _build(TelemetryConfig, data.get("telemetry", {}), "telemetry", src)
    est = _build(EstimatorsConfig, data.get("estimators", {}), "estimators", src)
    if est.airdata not in _AIRDATA:
        raise ConfigError(f"{src}: 'estimators.airdata' must be one of {_AIRDATA}, got "
                          f"{est.airdata!r}")
    sinks = _build(SinksConfig, data.get("sinks", {}), "sinks", src)
    fdi_data = data.get("fdi", {})
    if not isinstance(fdi_data, dict):
        raise ConfigError(f"{src}: [fdi] must be a table")
    sets = {}
    for key, value in fdi_data.items():
        if key not in _SET_UNITS:
            raise ConfigError(f"{src}: unknown key 'fdi.{key}'; expected one of "
                              f"{sorted(_SET_UNITS)}")
        sets[key] = _set_config(key, value, src)
    air = _airdata_config(data.get("airdata", {}), src)
    return MonitorConfig(telemetry=tel, fdi=dataclasses.replace(FdiConfig(), **sets),
                         estimators=est, sinks=sinks, airdata=air)
