"""Airframe data files (TOML in ``sim_vehicle/airframes/``) -> frozen :class:`Airframe`.

Every number of an airframe lives in its file, with its source; the code has none.
Unknown keys are rejected with an error naming the key and the file.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

AIRFRAME_DIR = Path(__file__).resolve().parent.parent / "airframes"


@dataclass(frozen=True, slots=True)
class MassProps:
    mass_kg: float
    jx_kgm2: float
    jy_kgm2: float
    jz_kgm2: float
    jxz_kgm2: float


@dataclass(frozen=True, slots=True)
class Geometry:
    wing_area_m2: float
    span_m: float
    chord_m: float


@dataclass(frozen=True, slots=True)
class AeroCoeffs:
    """Non-dimensional stability and control derivatives (per rad); see the airframe file."""

    cl0: float
    cl_alpha: float
    cl_q: float
    cl_de: float
    cd0: float
    cd_alpha: float
    cd_de: float
    cl_mindrag: float
    oswald_e: float
    cm0: float
    cm_alpha: float
    cm_q: float
    cm_de: float
    cy_beta: float
    cy_p: float
    cy_r: float
    cy_da: float
    cy_dr: float
    croll_beta: float
    croll_p: float
    croll_r: float
    croll_da: float
    croll_dr: float
    cn_beta: float
    cn_p: float
    cn_r: float
    cn_da: float
    cn_dr: float
    cl_alphadot: float = 0.0
    cm_alphadot: float = 0.0
    stall_blend_m: float = 0.0  # 0 = no stall blending
    stall_alpha0_rad: float = 0.0


@dataclass(frozen=True, slots=True)
class Propulsion:
    model: str  # "prop" (Beard eq. 4.18) or "jet"
    time_constant_s: float
    s_prop_m2: float = 0.0
    c_prop: float = 0.0
    k_motor_mps: float = 0.0
    max_thrust_n: float = 0.0
    density_exponent: float = 0.0


@dataclass(frozen=True, slots=True)
class Actuators:
    rod_gain_radpm: float
    rod_stroke_m: float
    max_deflection_rad: tuple[float, float, float]


@dataclass(frozen=True, slots=True)
class AutopilotGains:
    rate_bw_radps: float
    attitude_bw_radps: float
    altitude_bw_radps: float
    altitude_ki: float
    speed_kp_per_mps: float
    speed_ki_per_mps_s: float
    heading_bw_radps: float
    beta_gain: float
    max_pitch_rad: float
    max_bank_rad: float
    max_climb_mps: float
    doublet_amplitude_rad: float
    doublet_period_s: float
    climb_amplitude_m: float
    decel_amplitude_mps: float
    decel_rate_mps2: float
    parabola_gamma_rad: float
    parabola_pull_g: float


@dataclass(frozen=True, slots=True)
class Airframe:
    name: str
    source: str
    mass: MassProps
    geometry: Geometry
    aero: AeroCoeffs
    propulsion: Propulsion
    actuators: Actuators
    default_tas_mps: float
    autopilot: AutopilotGains


def _build(cls: type, table: dict[str, Any], section: str, path: Path) -> Any:
    names = {f.name for f in fields(cls)}
    for key in table:
        if key not in names:
            raise ValueError(f"{path}: unknown key {section}.{key}")
    kw = dict(table)
    if cls is Actuators:
        kw["max_deflection_rad"] = tuple(float(v) for v in kw["max_deflection_rad"])
    try:
        return cls(**kw)
    except TypeError as exc:
        raise ValueError(f"{path}: section [{section}]: {exc}") from exc


def load_airframe(name_or_path: str | Path) -> Airframe:
    """Load ``uav``/``transport`` (a file in ``sim_vehicle/airframes``) or a TOML path."""
    path = Path(name_or_path)
    if not path.suffix:
        path = AIRFRAME_DIR / f"{name_or_path}.toml"
    with path.open("rb") as fh:
        data = tomllib.load(fh)
    allowed = {"meta", "mass", "geometry", "aero", "propulsion", "actuators", "trim", "autopilot"}
    for key in data:
        if key not in allowed:
            raise ValueError(f"{path}: unknown section [{key}]")
    trim = data["trim"]
    for key in trim:
        if key != "default_tas_mps":
            raise ValueError(f"{path}: unknown key trim.{key}")
    return Airframe(
        name=data["meta"]["name"],
        source=data["meta"]["source"],
        mass=_build(MassProps, data["mass"], "mass", path),
        geometry=_build(Geometry, data["geometry"], "geometry", path),
        aero=_build(AeroCoeffs, data["aero"], "aero", path),
        propulsion=_build(Propulsion, data["propulsion"], "propulsion", path),
        actuators=_build(Actuators, data["actuators"], "actuators", path),
        default_tas_mps=float(trim["default_tas_mps"]),
        autopilot=_build(AutopilotGains, data["autopilot"], "autopilot", path),
    )
