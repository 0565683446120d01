"""Dashboard of the air-data family (pure data; ``dashboards/`` builds the Rerun blueprint)."""

from __future__ import annotations

from gcs_monitor.families.airdata.config import AirDataFamilyConfig
from gcs_monitor.families.airdata.family import SETS
from gcs_monitor.families.base import FamilyViews, PlotSpec


def _fused(s: str, *, reference: bool) -> PlotSpec:
    contents = ("+ $origin/measured/**", "+ $origin/fused")
    return PlotSpec(f"{s}: measured vs fused", ("sets", s),
                    contents + (("+ $origin/reference",) if reference else ()))


def _rms(s: str) -> PlotSpec:
    return PlotSpec(f"{s}: residual RMS vs threshold", ("sets", s),
                    ("+ $origin/rms/**", "+ $origin/threshold"))


def views(cfg: AirDataFamilyConfig) -> FamilyViews:
    """Per redundant set: measured vs fused, residual RMS vs threshold, voting weights."""
    columns = tuple(
        (f"Air data {s}", (_fused(s, reference=True), _rms(s),
                           PlotSpec(f"{s}: voting weights", ("sets", s, "weight"))))
        for s in SETS)
    return FamilyViews("Air data", columns,
                       overview=(_fused(SETS[0], reference=False), _rms(SETS[0])))
