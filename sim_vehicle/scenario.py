"""Scenario files: TOML -> frozen :class:`Scenario`, validated once, strictly.

Layout (every key carries its unit; deg, kts and ft are accepted and converted to SI)::

    [scenario]   name, description, airframe, duration_s, seed, dt_s
    [initial]    lat_deg, lon_deg, alt_m|alt_ft, tas_mps|tas_kts, heading_deg
    [wind]       kind, mean_ned_mps|mean_ned_kts, turbulence_sigma_mps|_kts,
                 turbulence_scale_m|_ft, shear_start_s, shear_amplitude_mps|_kts
    [manoeuvre]  kind, start_s, amplitude_deg|amplitude_rad, surface, period_s, repeat
    [sensors]    set ("lu2016"|"atmaca2025"), n_imu, imu_hz, attitude_hz, gps_hz, airdata_hz,
                 baro_hz, static_hz, gps_latency_s
    [output]     sysid, heartbeat_hz, servo_output_raw_hz, surf_hz, nav_hz, truth_hz,
                 servo_max_deflection_deg
    [[faults]]           channel, kind, t_start_s, [t_end_s], parameters (profiles.py)
    [[actuator_faults]]  surface, kind, t_start_s, [t_end_s], amplitude|amplitude_m,
                         frequency_hz, phase_deg

Any error raises :class:`ScenarioError` naming the file, the key and what is expected.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field, fields, replace
from importlib import resources
from pathlib import Path
from typing import Any

from gcs_monitor.core.units import DEG2RAD
from sim_vehicle.actuators.faults import (
    ACTUATORS,
    ENGINE,
    ENGINE_FAULT_KINDS,
    SURFACE_FAULT_KINDS,
    SURFACES,
    ActuatorFault,
)
from sim_vehicle.faults.profiles import (
    FAULT_KINDS,
    KIND_PARAMS,
    REPLACING_KINDS,
    ExpressionError,
    FaultSpec,
    compile_expression,
)
from sim_vehicle.faults.units import UNITS, accepted_suffixes, si_unit, split_key
from sim_vehicle.sensors.channels import MAX_IMU, channel_catalogue
from sim_vehicle.sensors.noise import SENSOR_SETS, SensorRates

WIND_KINDS = ("calm", "constant", "shear", "turbulence", "shear+turbulence")
MANOEUVRE_KINDS = (
    "level", "doublet_3211", "s_turn", "parabolic", "coordinated_turn", "decel", "climb",
)
# unit of ManoeuvreConfig.amplitude per kind (sim_vehicle/autopilot/manoeuvres.py); others: angle
MANOEUVRE_AMPLITUDE_DIM = {"decel": "speed", "climb": "length"}
SECTIONS = ("scenario", "initial", "wind", "manoeuvre", "sensors", "output", "faults",
            "actuator_faults")


class ScenarioError(ValueError):
    """A scenario file is invalid; the message names the file, the key and the expectation."""


@dataclass(frozen=True, slots=True)
class InitialSpec:
    """Mirrors ``sim_vehicle.physics.InitialCondition`` (SI except lat/lon/heading in deg)."""

    lat_deg: float = 52.0
    lon_deg: float = 4.4
    alt_m: float = 1000.0
    tas_mps: float | None = None
    heading_deg: float = 0.0


@dataclass(frozen=True, slots=True)
class WindSpec:
    """Mirrors ``sim_vehicle.physics.WindConfig``."""

    kind: str = "calm"
    mean_ned_mps: tuple[float, float, float] = (0.0, 0.0, 0.0)
    turbulence_sigma_mps: float = 3.54
    turbulence_scale_m: float = 530.0
    shear_start_s: float = 15.0
    shear_amplitude_mps: float = 10.0


@dataclass(frozen=True, slots=True)
class ManoeuvreSpec:
    """Mirrors ``sim_vehicle.physics.ManoeuvreConfig``.

    ``amplitude`` is SI with a meaning per kind: rad (doublet, s_turn, parabolic, turn),
    m/s (decel), m (climb); 0 = the airframe's default.
    """

    kind: str = "level"
    start_s: float = 10.0
    amplitude: float = 0.0
    surface: str = "elevator"
    period_s: float = 0.0
    repeat: bool = False


@dataclass(frozen=True, slots=True)
class SensorConfig:
    set_name: str = "lu2016"
    n_imu: int = 3
    rates: SensorRates = field(default_factory=SensorRates)
    gps_latency_s: float = 0.0


@dataclass(frozen=True, slots=True)
class OutputConfig:
    """Rates of the messages that carry no sensor sample, and link identity."""

    sysid: int = 1
    heartbeat_hz: float = 1.0  # docs/telemetry.md
    servo_output_raw_hz: float = 10.0  # docs/telemetry.md
    surf_hz: float = 50.0  # DEBUG_FLOAT_ARRAY SURF, docs/telemetry.md
    nav_hz: float = 10.0  # NAV_CONTROLLER_OUTPUT + ATTITUDE_TARGET, docs/telemetry.md
    truth_hz: float = 100.0
    servo_max_deflection_rad: float = 25.0 * DEG2RAD  # PWM 1500 +- 500 spans +-this


@dataclass(frozen=True, slots=True)
class Scenario:
    name: str
    description: str
    airframe: str
    duration_s: float
    seed: int
    dt_s: float
    initial: InitialSpec
    wind: WindSpec
    manoeuvre: ManoeuvreSpec
    sensors: SensorConfig
    output: OutputConfig
    faults: tuple[FaultSpec, ...] = ()
    actuator_faults: tuple[ActuatorFault, ...] = ()
    source: str = "<memory>"  # file the scenario was read from


# ---------------------------------------------------------------------------------------------
# table reader with key tracking
# ---------------------------------------------------------------------------------------------


class _Table:
    def __init__(self, data: dict[str, Any], where: str, src: str) -> None:
        if not isinstance(data, dict):
            raise ScenarioError(f"{src}: [{where}] must be a table")
        self.d = data
        self.where = where
        self.src = src
        self.used: set[str] = set()

    def err(self, key: str, msg: str) -> ScenarioError:
        return ScenarioError(f"{self.src}: [{self.where}] key '{key}': {msg}")

    def take(self, key: str, typ: type | tuple[type, ...], default: Any = ...) -> Any:
        if key not in self.d:
            if default is ...:
                raise ScenarioError(f"{self.src}: [{self.where}] missing required key '{key}'")
            return default
        self.used.add(key)
        v = self.d[key]
        if typ is float and isinstance(v, int) and not isinstance(v, bool):
            v = float(v)
        if not isinstance(v, typ) or (typ in (int, float) and isinstance(v, bool)):
            raise self.err(key, f"expected {getattr(typ, '__name__', typ)}, got {v!r}")
        if isinstance(v, float) and not math.isfinite(v):
            raise self.err(key, "must be finite")
        return v

    def take_unit(self, stem: str, dimension: str, default: Any = ..., *,
                  per_s: bool = False) -> Any:
        """A value given as ``<stem>_<unit>``, converted to SI; rejects unknown units."""
        found = []
        for k in self.d:
            if k == stem or k.startswith(stem + "_"):
                sp = split_key(k, dimension)
                if sp is not None and sp[0] == stem and sp[2] == per_s:
                    found.append((k, sp[1]))
                elif k == stem or _looks_like_unit(k, stem):
                    ok = [stem + "_" + u for u in accepted_suffixes(dimension, per_s=per_s)]
                    raise self.err(k, f"expected one of {ok}")
        if len(found) > 1:
            raise self.err(found[1][0], f"given twice (also as '{found[0][0]}')")
        if not found:
            if default is ...:
                raise ScenarioError(
                    f"{self.src}: [{self.where}] missing required key "
                    f"{stem}_<unit>, unit one of {accepted_suffixes(dimension, per_s=per_s)}")
            return default
        key, unit = found[0]
        self.used.add(key)
        v = self.d[key]
        factor = UNITS[dimension][unit]
        if isinstance(v, list):
            if not all(isinstance(x, int | float) and not isinstance(x, bool) for x in v):
                raise self.err(key, f"expected numbers, got {v!r}")
            return tuple(float(x) * factor for x in v)
        if isinstance(v, bool) or not isinstance(v, int | float):
            raise self.err(key, f"expected a number, got {v!r}")
        return float(v) * factor

    def finish(self) -> None:
        extra = sorted(set(self.d) - self.used)
        if extra:
            raise self.err(extra[0], "unknown key")


def _looks_like_unit(key: str, stem: str) -> bool:
    """``key`` is ``stem_<something>`` where something is not another parameter's stem."""
    rest = key[len(stem) + 1:]
    all_units = {u for d in UNITS.values() for u in d} | {"s", "hz", "kt", "knots", "fps", "ms"}
    first = rest.split("_")[0]
    return first in all_units or rest.endswith("per_s")


def _positive(t: _Table, key: str, v: float) -> float:
    if v <= 0:
        raise t.err(key, f"must be > 0, got {v}")
    return v


# ---------------------------------------------------------------------------------------------
# sections
# ---------------------------------------------------------------------------------------------


def _read_initial(t: _Table) -> InitialSpec:
    d = InitialSpec()
    lat = t.take("lat_deg", float, d.lat_deg)
    if not -90.0 <= lat <= 90.0:
        raise t.err("lat_deg", "expected -90..90 deg")
    tas = t.take_unit("tas", "speed", None)
    if tas is not None:
        _positive(t, "tas", tas)
    out = InitialSpec(
        lat_deg=lat,
        lon_deg=t.take("lon_deg", float, d.lon_deg),
        alt_m=t.take_unit("alt", "length", d.alt_m),
        tas_mps=tas,
        heading_deg=t.take("heading_deg", float, d.heading_deg),
    )
    t.finish()
    return out


def _read_wind(t: _Table) -> WindSpec:
    d = WindSpec()
    kind = t.take("kind", str, d.kind)
    if kind not in WIND_KINDS:
        raise t.err("kind", f"expected one of {WIND_KINDS}, got {kind!r}")
    mean = t.take_unit("mean_ned", "speed", d.mean_ned_mps)
    if not isinstance(mean, tuple) or len(mean) != 3:
        raise t.err("mean_ned_mps", "expected a list of 3 numbers [N, E, D]")
    out = WindSpec(
        kind=kind,
        mean_ned_mps=mean,
        turbulence_sigma_mps=t.take_unit("turbulence_sigma", "speed", d.turbulence_sigma_mps),
        turbulence_scale_m=t.take_unit("turbulence_scale", "length", d.turbulence_scale_m),
        shear_start_s=t.take("shear_start_s", float, d.shear_start_s),
        shear_amplitude_mps=t.take_unit("shear_amplitude", "speed", d.shear_amplitude_mps),
    )
    t.finish()
    return out


def _read_manoeuvre(t: _Table) -> ManoeuvreSpec:
    d = ManoeuvreSpec()
    kind = t.take("kind", str, d.kind)
    if kind not in MANOEUVRE_KINDS:
        raise t.err("kind", f"expected one of {MANOEUVRE_KINDS}, got {kind!r}")
    surface = t.take("surface", str, d.surface)
    if surface not in SURFACES:
        raise t.err("surface", f"expected one of {SURFACES}, got {surface!r}")
    out = ManoeuvreSpec(
        kind=kind,
        start_s=t.take("start_s", float, d.start_s),
        amplitude=t.take_unit("amplitude", MANOEUVRE_AMPLITUDE_DIM.get(kind, "angle"),
                              d.amplitude),
        surface=surface,
        period_s=t.take("period_s", float, d.period_s),
        repeat=t.take("repeat", bool, d.repeat),
    )
    t.finish()
    return out


def _read_sensors(t: _Table) -> SensorConfig:
    set_name = t.take("set", str, "lu2016")
    if set_name not in SENSOR_SETS:
        raise t.err("set", f"expected one of {sorted(SENSOR_SETS)}, got {set_name!r}")
    n_imu = t.take("n_imu", int, 3)
    if not 1 <= n_imu <= MAX_IMU:
        raise t.err("n_imu", f"expected 1..{MAX_IMU}, got {n_imu}")
    base = SENSOR_SETS[set_name].rates
    rates = {}
    for f in fields(SensorRates):
        rates[f.name] = _positive(t, f.name, t.take(f.name, float, getattr(base, f.name)))
    gps = rates["gps_hz"]
    if not 1.0 <= gps <= 10.0:
        raise t.err("gps_hz", f"expected 1..10 Hz, got {gps}")
    lat = t.take("gps_latency_s", float, 0.0)
    if lat < 0:
        raise t.err("gps_latency_s", "must be >= 0")
    t.finish()
    return SensorConfig(set_name, n_imu, SensorRates(**rates), lat)


def _read_output(t: _Table) -> OutputConfig:
    d = OutputConfig()
    sysid = t.take("sysid", int, d.sysid)
    if not 1 <= sysid <= 255:
        raise t.err("sysid", "expected 1..255")
    out = OutputConfig(
        sysid=sysid,
        heartbeat_hz=_positive(t, "heartbeat_hz", t.take("heartbeat_hz", float, d.heartbeat_hz)),
        servo_output_raw_hz=_positive(
            t, "servo_output_raw_hz", t.take("servo_output_raw_hz", float, d.servo_output_raw_hz)),
        surf_hz=_positive(t, "surf_hz", t.take("surf_hz", float, d.surf_hz)),
        nav_hz=_positive(t, "nav_hz", t.take("nav_hz", float, d.nav_hz)),
        truth_hz=_positive(t, "truth_hz", t.take("truth_hz", float, d.truth_hz)),
        servo_max_deflection_rad=t.take_unit(
            "servo_max_deflection", "angle", d.servo_max_deflection_rad),
    )
    t.finish()
    return out


def _read_fault(t: _Table, catalogue: dict[str, Any]) -> FaultSpec:
    channel = t.take("channel", str)
    if channel not in catalogue:
        raise t.err("channel", f"no channel {channel!r} in this scenario; expected one of "
                    f"{sorted(catalogue)}")
    kind = t.take("kind", str)
    if kind not in FAULT_KINDS:
        raise t.err("kind", f"expected one of {FAULT_KINDS}, got {kind!r}")
    t0 = t.take("t_start_s", float)
    if t0 < 0:
        raise t.err("t_start_s", "must be >= 0")
    t1 = t.take("t_end_s", float, None)
    if t1 is not None and t1 <= t0:
        raise t.err("t_end_s", f"must be > t_start_s = {t0}")
    dim = catalogue[channel].dimension
    si = si_unit(dim)
    params: list[tuple[str, object]] = []
    for stem, (required, ukind) in KIND_PARAMS[kind].items():
        if ukind == "fixed":
            v = t.take(stem, float, ... if required else None)
            if v is not None:
                params.append((stem, v))
        elif ukind == "angle":
            v = t.take_unit(stem, "angle", ... if required else None)
            if v is not None:
                params.append((f"{stem}_rad", v))
        elif stem == "expr":
            found = [k for k in t.d if k.startswith("expr_")]
            if len(found) != 1 or split_key(found[0], dim) is None:
                raise t.err(found[0] if found else "expr",
                            f"{channel} is {dim}: expected exactly one of "
                            f"{['expr_' + u for u in accepted_suffixes(dim)]}")
            key = found[0]
            text = t.take(key, str)
            try:
                compile_expression(text)
            except ExpressionError as e:
                raise t.err(key, str(e)) from None
            unit = split_key(key, dim)[1]  # type: ignore[index]
            params += [(f"expr_{si}", text), ("si_factor", UNITS[dim][unit])]
        else:
            per_s = ukind == "u/s"
            try:
                v = t.take_unit(stem, dim, ... if required else None, per_s=per_s)
            except ScenarioError as e:
                raise ScenarioError(f"{e} ({channel} is {dim})") from None
            if v is not None:
                params.append((f"{stem}_{si}" + ("_per_s" if per_s else ""), v))
    if kind == "nrz" and len(params) > 1:
        raise t.err("gain", "give either level (the output falls to level x the value) or gain "
                    "(an additive gain x the value), not both")
    t.finish()
    return FaultSpec(channel, kind, t0, t1, tuple(params))


def _read_actuator_fault(t: _Table) -> ActuatorFault:
    surface = t.take("surface", str)
    if surface not in ACTUATORS:
        raise t.err("surface", f"expected one of {ACTUATORS}, got {surface!r}")
    kind = t.take("kind", str)
    kinds = ENGINE_FAULT_KINDS if ACTUATORS.index(surface) == ENGINE else SURFACE_FAULT_KINDS
    if kind not in kinds:
        raise t.err("kind", f"expected one of {kinds} on the {surface}, got {kind!r}")
    t0 = t.take("t_start_s", float, 12.0)
    t1 = t.take("t_end_s", float, None)
    if t1 is not None and t1 <= t0:
        raise t.err("t_end_s", f"must be > t_start_s = {t0}")
    if kind == "liquid_jam":
        amp = t.take_unit("amplitude", "length")  # rod-sensor bias, m
    elif kind in ("liquid_ofc", "solid_ofc"):
        amp = t.take("amplitude", float)  # valve-command units (-)
    elif kind == "loss_of_effectiveness":
        amp = t.take("amplitude", float)  # share of the effect lost
        if not 0.0 < amp <= 1.0:
            raise t.err("amplitude", f"the share of the effect lost: 0 < amplitude <= 1, got {amp}")
    else:
        amp = t.take("amplitude", float, 1.0 if kind == "runaway" else 0.0)
    freq = t.take("frequency_hz", float, 0.0)
    if kind.endswith("_ofc") and freq <= 0:
        raise t.err("frequency_hz", "an OFC needs frequency_hz > 0")
    phase = t.take_unit("phase", "angle", 0.0)
    t.finish()
    return ActuatorFault(ACTUATORS.index(surface), kind, t0, t1, amp, freq, phase)


def _check_overlaps(faults: tuple[FaultSpec, ...], src: str) -> None:
    """Two faults on one channel at the same time contradict if one jams or both are alike."""
    for i, a in enumerate(faults):
        for j in range(i + 1, len(faults)):
            b = faults[j]
            if a.channel != b.channel:
                continue
            a1 = math.inf if a.t_end_s is None else a.t_end_s
            b1 = math.inf if b.t_end_s is None else b.t_end_s
            if max(a.t_start_s, b.t_start_s) < min(a1, b1) and (
                a.kind == b.kind or a.kind in REPLACING_KINDS or b.kind in REPLACING_KINDS
            ):
                raise ScenarioError(
                    f"{src}: [[faults]] #{j + 1} key 'channel': {b.kind} on {b.channel} overlaps "
                    f"{a.kind} (#{i + 1}) in time; expected non-overlapping intervals for "
                    f"faults of the same kind or a jam")


def airframe_names() -> list[str]:
    d = resources.files("sim_vehicle") / "airframes"
    try:
        return sorted(p.name[:-5] for p in d.iterdir() if p.name.endswith(".toml"))
    except (FileNotFoundError, NotADirectoryError):
        return []


def parse_scenario(text: str, source: str = "<string>") -> Scenario:
    """Parse and validate scenario TOML text."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ScenarioError(f"{source}: not valid TOML: {e}") from None
    for k in data:
        if k not in SECTIONS:
            raise ScenarioError(f"{source}: unknown section [{k}]; expected one of {SECTIONS}")
    s = _Table(data.get("scenario", {}), "scenario", source)
    name = s.take("name", str, Path(source).stem)
    description = s.take("description", str, "")
    airframe = s.take("airframe", str)
    known = airframe_names()
    if known and airframe not in known:
        raise s.err("airframe", f"expected one of {known}, got {airframe!r}")
    duration = _positive(s, "duration_s", s.take("duration_s", float))
    seed = s.take("seed", int, 0)
    dt = _positive(s, "dt_s", s.take("dt_s", float, 0.01))
    s.finish()
    sensors = _read_sensors(_Table(data.get("sensors", {}), "sensors", source))
    for f in fields(SensorRates):
        hz = getattr(sensors.rates, f.name)
        if hz > 1.0 / dt * (1 + 1e-9):
            raise ScenarioError(f"{source}: [sensors] key '{f.name}': {hz} Hz exceeds the "
                                f"simulation rate 1/dt_s = {1 / dt:g} Hz")
    catalogue = channel_catalogue(sensors.n_imu)
    raw_faults = data.get("faults", [])
    if not isinstance(raw_faults, list):
        raise ScenarioError(f"{source}: 'faults' must be an array of tables [[faults]]")
    faults = tuple(
        _read_fault(_Table(f, f"[faults] #{i + 1}", source), catalogue)
        for i, f in enumerate(raw_faults)
    )
    _check_overlaps(faults, source)
    raw_act = data.get("actuator_faults", [])
    if not isinstance(raw_act, list):
        raise ScenarioError(f"{source}: 'actuator_faults' must be an array [[actuator_faults]]")
    act = tuple(_read_actuator_fault(_Table(f, f"[actuator_faults] #{i + 1}", source))
                for i, f in enumerate(raw_act))
    return Scenario(
        name=name,
        description=description,
        airframe=airframe,
        duration_s=duration,
        seed=seed,
        dt_s=dt,
        initial=_read_initial(_Table(data.get("initial", {}), "initial", source)),
        wind=_read_wind(_Table(data.get("wind", {}), "wind", source)),
        manoeuvre=_read_manoeuvre(_Table(data.get("manoeuvre", {}), "manoeuvre", source)),
        sensors=sensors,
        output=_read_output(_Table(data.get("output", {}), "output", source)),
        faults=faults,
        actuator_faults=act,
        source=source,
    )


# ---------------------------------------------------------------------------------------------
# presets, files, serialisation
# ---------------------------------------------------------------------------------------------


def preset_dir() -> Path:
    return Path(str(resources.files("sim_vehicle") / "presets"))


def list_presets() -> list[tuple[str, str]]:
    """(name, one-line description) of every preset, sorted by name."""
    out = []
    for p in sorted(preset_dir().glob("*.toml")):
        try:
            desc = tomllib.loads(p.read_text()).get("scenario", {}).get("description", "")
        except tomllib.TOMLDecodeError:
            desc = "(invalid TOML)"
        out.append((p.stem, str(desc).splitlines()[0] if desc else ""))
    return out


def load_scenario(name_or_path: str | Path) -> Scenario:
    """A preset by name (``lu2016_calm``) or a scenario TOML file by path."""
    p = Path(name_or_path)
    if not p.is_file():
        cand = preset_dir() / f"{name_or_path}.toml"
        if not cand.is_file():
            names = [n for n, _ in list_presets()]
            raise ScenarioError(f"{name_or_path}: no such file or preset; presets: {names}")
        p = cand
    return parse_scenario(p.read_text(), str(p))


def _fmt(v: object) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, tuple | list):
        return "[" + ", ".join(_fmt(x) for x in v) + "]"
    return repr(float(v)) if isinstance(v, float) else str(v)


def to_toml(sc: Scenario) -> str:
    """Serialise a Scenario to TOML (SI keys) such that ``parse_scenario`` gives it back."""
    lines = ["[scenario]"]
    for k, v in (("name", sc.name), ("description", sc.description), ("airframe", sc.airframe),
                 ("duration_s", sc.duration_s), ("seed", sc.seed), ("dt_s", sc.dt_s)):
        lines.append(f"{k} = {_fmt(v)}")
    i = sc.initial
    lines += ["", "[initial]", f"lat_deg = {_fmt(i.lat_deg)}", f"lon_deg = {_fmt(i.lon_deg)}",
              f"alt_m = {_fmt(i.alt_m)}", f"heading_deg = {_fmt(i.heading_deg)}"]
    if i.tas_mps is not None:
        lines.append(f"tas_mps = {_fmt(i.tas_mps)}")
    w = sc.wind
    lines += ["", "[wind]", f"kind = {_fmt(w.kind)}", f"mean_ned_mps = {_fmt(w.mean_ned_mps)}",
              f"turbulence_sigma_mps = {_fmt(w.turbulence_sigma_mps)}",
              f"turbulence_scale_m = {_fmt(w.turbulence_scale_m)}",
              f"shear_start_s = {_fmt(w.shear_start_s)}",
              f"shear_amplitude_mps = {_fmt(w.shear_amplitude_mps)}"]
    m = sc.manoeuvre
    lines += ["", "[manoeuvre]", f"kind = {_fmt(m.kind)}", f"start_s = {_fmt(m.start_s)}",
              f"amplitude_{si_unit(MANOEUVRE_AMPLITUDE_DIM.get(m.kind, 'angle'))} = "
              f"{_fmt(m.amplitude)}", f"surface = {_fmt(m.surface)}",
              f"period_s = {_fmt(m.period_s)}", f"repeat = {_fmt(m.repeat)}"]
    s = sc.sensors
    lines += ["", "[sensors]", f"set = {_fmt(s.set_name)}", f"n_imu = {s.n_imu}",
              f"gps_latency_s = {_fmt(s.gps_latency_s)}"]
    lines += [f"{f.name} = {_fmt(getattr(s.rates, f.name))}" for f in fields(SensorRates)]
    o = sc.output
    lines += ["", "[output]", f"sysid = {o.sysid}", f"heartbeat_hz = {_fmt(o.heartbeat_hz)}",
              f"servo_output_raw_hz = {_fmt(o.servo_output_raw_hz)}",
              f"surf_hz = {_fmt(o.surf_hz)}", f"nav_hz = {_fmt(o.nav_hz)}",
              f"truth_hz = {_fmt(o.truth_hz)}",
              f"servo_max_deflection_rad = {_fmt(o.servo_max_deflection_rad)}"]
    for f in sc.faults:
        lines += ["", "[[faults]]", f"channel = {_fmt(f.channel)}", f"kind = {_fmt(f.kind)}",
                  f"t_start_s = {_fmt(f.t_start_s)}"]
        if f.t_end_s is not None:
            lines.append(f"t_end_s = {_fmt(f.t_end_s)}")
        p = f.p()
        factor = float(p.pop("si_factor", 1.0))  # type: ignore[arg-type]
        for k, value in p.items():
            if k.startswith("expr_"):
                k = "expr_" + _unit_with_factor(k[len("expr_"):], factor)
            lines.append(f"{k} = {_fmt(value)}")
    for a in sc.actuator_faults:
        lines += ["", "[[actuator_faults]]", f"surface = {_fmt(ACTUATORS[a.surface])}",
                  f"kind = {_fmt(a.kind)}", f"t_start_s = {_fmt(a.t_start_s)}"]
        if a.t_end_s is not None:
            lines.append(f"t_end_s = {_fmt(a.t_end_s)}")
        lines.append(("amplitude_m" if a.kind == "liquid_jam" else "amplitude")
                     + f" = {_fmt(a.amplitude)}")
        lines += [f"frequency_hz = {_fmt(a.frequency_hz)}", f"phase_rad = {_fmt(a.phase_rad)}"]
    return "\n".join(lines) + "\n"


def _unit_with_factor(si: str, factor: float) -> str:
    """The config unit of the dimension whose SI unit is ``si`` with this factor to SI."""
    for units in UNITS.values():
        if next(iter(units)) == si:
            for u, f in units.items():
                if f == factor:
                    return u
    raise ValueError(f"no unit with factor {factor} for {si}")


def with_overrides(sc: Scenario, *, duration_s: float | None = None,
                   seed: int | None = None) -> Scenario:
    """A copy with the CLI overrides applied."""
    kw: dict[str, Any] = {}
    if duration_s is not None:
        if duration_s <= 0:
            raise ScenarioError(f"--duration: must be > 0, got {duration_s}")
        kw["duration_s"] = float(duration_s)
    if seed is not None:
        kw["seed"] = int(seed)
    return replace(sc, **kw)


__all__ = [
    "InitialSpec", "ManoeuvreSpec", "OutputConfig", "Scenario", "ScenarioError", "SensorConfig",
    "WindSpec", "list_presets", "load_scenario", "parse_scenario", "to_toml", "with_overrides",
]
