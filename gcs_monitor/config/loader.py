"""Monitor configuration: TOML -> frozen dataclasses, validated once; defaults printed and
documented from the same declarations.

The configuration is a ``[telemetry]`` and a ``[sinks]`` section plus one section per registered
family (``[imu]``, ``[airdata]``, ...; :mod:`gcs_monitor.families.registry`), each a tree of
the dataclasses that the code uses, declared with :func:`gcs_monitor.core.params.param`. Keys
carry their unit (``threshold_deg``, ``gps_delay_s``; the rules are in
:mod:`gcs_monitor.core.params`); values are converted to SI here, once. Unknown keys, wrong
types and out-of-range values stop with a message naming the file and the key. A file gives
only what differs from the defaults.
"""

from __future__ import annotations

import dataclasses
import tomllib
import typing
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from gcs_monitor.core.params import KeySpec, display, in_toml, key_spec, param, section
from gcs_monitor.families import registry
from gcs_monitor.fdi.alarms import AlarmParams, LinkAlarmParams
from gcs_monitor.fdi.classify import ClassifierShape
from gcs_monitor.fdi.coverage import CoverageConfig


class ConfigError(ValueError):
    """Invalid monitor configuration; the message names the file, the key and what is expected."""


@dataclass(frozen=True, slots=True)
class TelemetryConfig:
    """How Frames are assembled from the telemetry."""

    gps_delay_s: float = param(0.1, "least GPS velocity interpolation delay D: frames are held "
                               "this long so every input is aligned to the IMU time (one GPS "
                               "period at 10 Hz; Lu2016 sec. 5); it grows to the measured GPS "
                               "period of a slower GPS")
    stale_after_s: float = param(0.5, "an input older than this is invalid", positive=True)
    primary_imu: int = param(0, "preferred primary IMU instance (HIGHRES_IMU id)")


@dataclass(frozen=True, slots=True)
class SinksConfig:
    """Where alarms, estimates and health go."""

    rerun_rate_hz: float = param(20.0, "rate of the plotted values in the Rerun recording",
                                 positive=True)
    zenoh: bool = param(False, "publish alarms, estimates and health on Zenoh")
    zenoh_listen: tuple[str, ...] = param(("tcp/127.0.0.1:7447",), "Zenoh endpoints to listen "
                                          "on (peer mode)")
    zenoh_connect: tuple[str, ...] = param((), "Zenoh routers or peers to connect to")
    estimate_rate_hz: float = param(5.0, "rate of the estimates published on Zenoh",
                                    positive=True)
    queue_size: int = param(10_000, "bounded queue of a sink's publisher thread",
                            positive=True)


def default_families() -> dict[str, Any]:
    """Every registered family's default configuration, in registry order."""
    return {spec.name: spec.config() for spec in registry.FAMILIES}


@dataclass(frozen=True)
class MonitorConfig:
    """The whole monitor configuration (the defaults suit the simulated airframes).

    ``families`` maps each registered family's name to its configuration dataclass; use
    :meth:`family` and :meth:`with_family`.
    """

    telemetry: TelemetryConfig = section(TelemetryConfig, "frame assembly")
    link: LinkAlarmParams = section(LinkAlarmParams, "link-health alarms (never sensor faults)")
    alarms: AlarmParams = section(AlarmParams, "alarm update policy of every channel")
    classifier: ClassifierShape = section(ClassifierShape, "fault classification shape tests "
                                          "of every channel")
    coverage: CoverageConfig = section(CoverageConfig, "how much of the flight each family "
                                       "must judge (monitor_degraded alarms)")
    sinks: SinksConfig = section(SinksConfig, "outputs")
    families: Mapping[str, Any] = field(default_factory=default_families)

    def family(self, name: str) -> Any:
        """The configuration of family ``name``."""
        try:
            return self.families[name]
        except KeyError:
            raise KeyError(f"unknown family {name!r}; known: {sorted(self.families)}") from None

    def with_family(self, name: str, cfg: Any = None, **changes: Any) -> MonitorConfig:
        """A copy with family ``name`` replaced by ``cfg`` or by its current configuration with
        ``changes`` (``dataclasses.replace``)."""
        new = cfg if cfg is not None else dataclasses.replace(self.family(name), **changes)
        return dataclasses.replace(self, families={**self.families, name: new})


# Keys of the configuration before the families (old files): where each went.
_MOVED = {
    "fdi": "the FDI sets moved into their families: [fdi.aoa] -> [airdata.fdi.aoa], "
           "[fdi.cas] -> [airdata.fdi.cas], [fdi.acc] -> [imu.ts.fdi.acc], [fdi.gyro] -> "
           "[imu.ts.fdi.gyro], [fdi.acc_hosm] -> [imu.hosm.fdi.acc], [fdi.gyro_hosm] -> "
           "[imu.hosm.fdi.gyro]; n_eval/n_detect/n_clear became window_s/detect_ratio/clear_s",
    "estimators": "the estimators are chosen per family: [imu.ts] enabled, [imu.hosm] enabled, "
                  "[airdata] estimator = \"cmhe\"|\"umhe\"|\"ekf\"|\"none\"",
    "airdata.wind_accel_in_alpha": "it moved to [airdata.filter]",
    "airdata.lateral_terms": "it moved to [airdata.filter]",
    "n_eval": "windows are in seconds now: window_s (the RMS and confirmation window), "
              "detect_ratio (n_D / N_eval)",
    "n_detect": "give detect_ratio = n_D / N_eval",
    "n_clear": "give clear_s, the time below the clear level",
}
_WEATHER_KEYS = {"wind_kts", "wind_z_kts", "shear_kts", "shear_z_kts", "shear_rate_ktsps",
                 "turbulence_sigma_kts", "turbulence_scale_m", "n_sigma", "flight_path_max_deg",
                 "model_margin_kts", "model_rate_margin_ktsps"}


def _hint(where: str, key: str) -> str:
    full = f"{where}.{key}" if where else key
    if full in _MOVED:
        return f" ({_MOVED[full]})"
    if key in _MOVED and where:
        return f" ({_MOVED[key]})"
    if where == "airdata" and key in _WEATHER_KEYS:
        return f" (the declared weather moved to [airdata.weather]: {key})"
    return ""


def _specs(cls: type, unit: Any) -> Iterator[tuple[dataclasses.Field[Any], KeySpec]]:
    for f in dataclasses.fields(cls):
        if in_toml(f):
            yield f, key_spec(cls, f, unit)


def _parse(default: Any, data: Any, where: str, src: str, unit: Any = None) -> Any:
    """``default`` (a dataclass instance) with the keys of TOML table ``data`` applied."""
    if not isinstance(data, dict):
        raise ConfigError(f"{src}: [{where}] must be a table")
    cls = type(default)
    hints = typing.get_type_hints(cls)
    by_key = {spec.key: (f, spec) for f, spec in _specs(cls, unit)}
    changes: dict[str, Any] = {}
    for key, value in data.items():
        if key not in by_key:
            raise ConfigError(f"{src}: unknown key '{where}.{key}'{_hint(where, key)}; expected "
                              f"one of {sorted(by_key)}")
        f, spec = by_key[key]
        current = getattr(default, f.name)
        if dataclasses.is_dataclass(current):
            changes[f.name] = _parse(current, value, f"{where}.{key}", src,
                                     f.metadata.get("set_unit") or unit)
        else:
            changes[f.name] = _coerce(hints[f.name], value, spec, f"{where}.{key}", src)
    try:
        return dataclasses.replace(default, **changes)
    except (ValueError, TypeError) as exc:
        raise ConfigError(f"{src}: [{where}]: {exc}") from None


def _sign(spec: KeySpec) -> str:
    return "positive" if spec.positive else "non-negative"


def _number(value: Any, spec: KeySpec, key: str, src: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ConfigError(f"{src}: '{key}' must be a number, got {value!r}")
    if value < 0 or (spec.positive and value == 0):
        raise ConfigError(f"{src}: '{key}' must be a {_sign(spec)} number, got {value!r}")
    return float(value) * spec.factor


def _coerce(tp: Any, value: Any, spec: KeySpec, key: str, src: str) -> Any:
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if tp is bool:
        if not isinstance(value, bool):
            raise ConfigError(f"{src}: '{key}' must be true or false, got {value!r}")
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int) or value < 0 or (
                spec.positive and value == 0):
            raise ConfigError(f"{src}: '{key}' must be a {_sign(spec)} integer, got {value!r}")
        return value
    if tp is float:
        return _number(value, spec, key, src)
    if tp is str:
        if not isinstance(value, str):
            raise ConfigError(f"{src}: '{key}' must be a string, got {value!r}")
        if spec.choices is not None and value not in spec.choices:
            raise ConfigError(f"{src}: '{key}' must be one of {list(spec.choices)}, got {value!r}")
        return value
    if origin is tuple:
        if not isinstance(value, list):
            raise ConfigError(f"{src}: '{key}' must be a list, got {value!r}")
        fixed = not (len(args) == 2 and args[1] is Ellipsis)
        if fixed and len(value) != len(args):
            raise ConfigError(f"{src}: '{key}' must have {len(args)} elements, got {value!r}")
        item = args[0]
        if item is str:
            if not all(isinstance(v, str) for v in value):
                raise ConfigError(f"{src}: '{key}' must be a list of strings, got {value!r}")
            return tuple(value)
        return tuple(_number(v, spec, key, src) for v in value)
    raise ConfigError(f"{src}: '{key}' has an unsupported type {tp!r}")


def config_from_dict(data: Mapping[str, Any], src: str = "<config>", *,
                     base: MonitorConfig | None = None) -> MonitorConfig:
    """A :class:`MonitorConfig` from parsed TOML (``src`` names it in errors), over ``base``
    (default: the defaults)."""
    base = base if base is not None else MonitorConfig()
    top_names = [f.name for f in dataclasses.fields(base) if f.name != "families"]
    allowed = [*top_names, *base.families]
    for key in data:
        if key not in allowed:
            raise ConfigError(f"{src}: unknown section [{key}]{_hint('', key)}; expected one of "
                              f"{allowed}")
    top = {name: _parse(getattr(base, name), data.get(name, {}), name, src)
           for name in top_names}
    fams = {name: _parse(cfg, data.get(name, {}), name, src) for name, cfg in base.families.items()}
    return MonitorConfig(**top, families=fams)


def load_config(path: Path | None = None, *, base: MonitorConfig | None = None) -> MonitorConfig:
    """Load a monitor TOML file over ``base`` (default: the defaults, which suit the simulated
    airframes); ``None`` gives ``base``."""
    if path is None:
        return base if base is not None else MonitorConfig()
    src = str(path)
    try:
        with open(path, "rb") as fh:
            data = tomllib.load(fh)
    except FileNotFoundError:
        raise ConfigError(f"{src}: no such config file") from None
    except IsADirectoryError:
        raise ConfigError(f"{src}: is a directory, not a config file") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{src}: not valid TOML: {exc}") from None
    cfg: MonitorConfig = _files_beside(config_from_dict(data, src, base=base), Path(path).parent)
    return cfg


def _files_beside(obj: Any, folder: Path) -> Any:
    """``obj`` (a configuration dataclass) with every file parameter (``param(file=True)``)
    that names a relative file made relative to ``folder``, the configuration file's: a
    configuration and a file written beside it (``calibrate``'s yaw-rate design) move
    together. Names without a suffix (a shipped design) are left as they are."""
    changes: dict[str, Any] = {}
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        if f.metadata.get("file") and isinstance(value, str):
            path = Path(value)
            if path.suffix and not path.is_absolute():
                changes[f.name] = str(folder / path)
        elif isinstance(value, dict):  # the families
            new = {k: _files_beside(v, folder) if dataclasses.is_dataclass(v) else v
                   for k, v in value.items()}
            if any(new[k] is not value[k] for k in value):
                changes[f.name] = new
        elif dataclasses.is_dataclass(value) and not isinstance(value, type):
            sub = _files_beside(value, folder)
            if sub is not value:
                changes[f.name] = sub
    return dataclasses.replace(obj, **changes) if changes else obj


# -- printing -------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class Entry:
    """One key of the configuration: its table, TOML key, value (TOML units) and doc."""

    table: str
    key: str
    value: Any
    doc: str


@dataclass(frozen=True, slots=True)
class Table:
    """One TOML table: its dotted name, its doc and its keys."""

    name: str
    doc: str
    entries: tuple[Entry, ...]


def _shown(value: Any, spec: KeySpec) -> Any:
    if isinstance(value, bool) or isinstance(value, int | str):
        return value
    if isinstance(value, float):
        return display(value, spec.factor)
    if isinstance(value, tuple):
        return [v if isinstance(v, str) else display(float(v), spec.factor) for v in value]
    raise TypeError(f"cannot show {value!r}")


def _tables(obj: Any, name: str, doc: str, unit: Any, out: list[Table]) -> None:
    entries: list[Entry] = []
    nested: list[tuple[Any, str, str, Any]] = []
    for f, spec in _specs(type(obj), unit):
        value = getattr(obj, f.name)
        if dataclasses.is_dataclass(value):
            nested.append((value, f"{name}.{spec.key}", spec.doc,
                           f.metadata.get("set_unit") or unit))
        else:
            entries.append(Entry(name, spec.key, _shown(value, spec), spec.doc))
    out.append(Table(name, doc, tuple(entries)))
    for value, sub, sub_doc, sub_unit in nested:
        _tables(value, sub, sub_doc, sub_unit, out)


def config_tables(cfg: MonitorConfig | None = None) -> list[Table]:
    """Every table and key of ``cfg`` (default: the defaults), in TOML order."""
    c = cfg if cfg is not None else MonitorConfig()
    out: list[Table] = []
    for f in dataclasses.fields(c):
        if f.name != "families":
            _tables(getattr(c, f.name), f.name, f.metadata["doc"], None, out)
    for spec in registry.FAMILIES:
        if spec.name in c.families:
            _tables(c.families[spec.name], spec.name, spec.title, None, out)
    return out


def toml_value(v: Any) -> str:
    """A value as TOML writes it."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, float):
        return repr(v)
    return str(v)


def config_toml(cfg: MonitorConfig | None = None, *, comments: bool = True) -> str:
    """``cfg`` (default: the defaults) as a TOML file that :func:`load_config` reads back to
    the same configuration, with a comment per key."""
    lines: list[str] = []
    for t in config_tables(cfg):
        if not t.entries:
            continue
        if lines:
            lines.append("")
        if comments and t.doc:
            lines.append(f"# {t.doc}")
        lines.append(f"[{t.name}]")
        for e in t.entries:
            line = f"{e.key} = {toml_value(e.value)}"
            lines.append(f"{line}  # {e.doc}" if comments and e.doc else line)
    return "\n".join(lines) + "\n"


def config_markdown() -> str:
    """The configuration reference page (docs/configuration.md) of the defaults."""
    out = ["# Configuration", "",
           "Generated by `gcs-monitor config --markdown` from the declarations in the code; "
           "`tests/gcs_monitor/config/test_config_doc.py` keeps it in sync. Every key is "
           "optional: a file gives only what differs from these defaults, and "
           "`gcs-monitor config --defaults` prints them all as a TOML file. Units are in the "
           "key names (SI otherwise); an unknown key or a value out of range stops with a "
           "message naming the file and the key.", ""]
    for t in config_tables():
        if not t.entries:
            continue
        out += [f"## `[{t.name}]`", ""]
        if t.doc:
            out += [t.doc[0].upper() + t.doc[1:] + ".", ""]
        out += ["| key | default | meaning |", "|---|---|---|"]
        for e in t.entries:
            doc = e.doc.replace("|", "\\|")
            out.append(f"| `{e.key}` | `{toml_value(e.value)}` | {doc} |")
        out.append("")
    return "\n".join(out)
