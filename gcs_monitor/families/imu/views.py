"""Dashboard of the IMU family (pure data; ``dashboards/`` builds the Rerun blueprint)."""

from __future__ import annotations

from gcs_monitor.families.base import FamilyViews, PlotSpec
from gcs_monitor.families.imu.config import ImuFamilyConfig

KINDS = ("acc", "gyro")
INSTANCES = (0, 1, 2)
# Rerun entity filters accept "**" only as a trailing wildcard, so per-channel leaves are listed
# explicitly (x/y/z for acc, p/q/r for gyro; absent entities are simply not shown).
AXES = ("x", "y", "z", "p", "q", "r")


def _leaves(*leaves: str) -> tuple[str, ...]:
    return tuple(f"+ $origin/{i}/{ax}/{leaf}" for leaf in leaves for i in INSTANCES
                 for ax in AXES)


def _measured(kind: str) -> PlotSpec:
    return PlotSpec(f"{kind}: measured vs corrected", ("channels", kind),
                    _leaves("measured", "corrected"))


def _fault(kind: str) -> PlotSpec:
    return PlotSpec(f"{kind}: reconstructed vs true fault", ("channels", kind),
                    _leaves("fault/**", "true_fault"))


def views(cfg: ImuFamilyConfig) -> FamilyViews:
    """Per IMU kind: measured vs corrected, reconstructed vs true fault, RMS vs threshold."""
    columns = tuple(
        (f"IMU {k}", (_measured(k), _fault(k),
                      PlotSpec(f"{k}: residual RMS vs threshold", ("channels", k),
                               _leaves("rms", "threshold"))))
        for k in KINDS)
    return FamilyViews("IMU", columns, overview=(_measured(KINDS[0]), _fault(KINDS[0])))
