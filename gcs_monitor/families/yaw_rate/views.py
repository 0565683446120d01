"""Dashboard of the yaw-rate family (pure data; ``dashboards/`` builds the Rerun blueprint)."""

from __future__ import annotations

from gcs_monitor.families.base import FamilyViews, PlotSpec
from gcs_monitor.families.yaw_rate.config import YawRateFamilyConfig

INSTANCES = (0, 1, 2)


def _leaves(axis: str, *leaves: str) -> tuple[str, ...]:
    return tuple(f"+ $origin/{i}/{axis}/{leaf}" for leaf in leaves for i in INSTANCES)


def views(cfg: YawRateFamilyConfig) -> FamilyViews:
    """Measured vs corrected gyro, reconstructed vs true fault, RMS vs threshold."""
    ax = cfg.sensor
    measured = PlotSpec(f"gyro {ax}: measured vs corrected (Chen2020)", ("channels", "gyro"),
                        _leaves(ax, "measured", "corrected"))
    fault = PlotSpec(f"gyro {ax}: reconstructed vs true fault", ("channels", "gyro"),
                     _leaves(ax, "fault/**", "true_fault"))
    rms = PlotSpec(f"gyro {ax}: residual RMS vs threshold", ("channels", "gyro"),
                   _leaves(ax, "rms", "threshold"))
    return FamilyViews("Yaw rate", ((f"gyro {ax}", (measured, fault, rms)),),
                       overview=(fault,))
