"""The monitored families, in the order the pipeline runs them. A new family is a new package
under ``gcs_monitor/families/`` and one line here."""

from __future__ import annotations

from gcs_monitor.families import actuators, airdata, imu, yaw_rate
from gcs_monitor.families.base import FamilySpec

FAMILIES: tuple[FamilySpec, ...] = (
    imu.SPEC,
    airdata.SPEC,
    yaw_rate.SPEC,
    actuators.SPEC,
)


def family_spec(name: str) -> FamilySpec:
    """The registered family called ``name`` (KeyError naming the known ones otherwise)."""
    for spec in FAMILIES:
        if spec.name == name:
            return spec
    raise KeyError(f"unknown family {name!r}; known: {[s.name for s in FAMILIES]}")
