"""Dashboard of the actuator family (pure data; ``dashboards/`` builds the Rerun blueprint).

Per surface: command, measured (SURF, where the vehicle reports it) and estimated position;
per actuator: the effectiveness estimate and the normalised residual's RMS against its
threshold, with the true fault beside it in evaluation (``log_true_faults``)."""

from __future__ import annotations

from gcs_monitor.families.actuators.aircraft import ESTIMATOR
from gcs_monitor.families.actuators.config import ACTUATORS, SURFACES, ActuatorFamilyConfig
from gcs_monitor.families.base import FamilyViews, PlotSpec


def _positions() -> PlotSpec:
    return PlotSpec("surfaces: command, measured, estimated position [rad]",
                    ("estimates", ESTIMATOR),
                    ("+ $origin/command_rad/**", "+ $origin/measured_position_rad/**",
                     "+ $origin/estimated_position_rad/**"))


def _effectiveness() -> PlotSpec:
    return PlotSpec("effectiveness (tracking / reference model)", ("estimates", ESTIMATOR),
                    ("+ $origin/effectiveness/**",))


def _rms(i: int, name: str) -> PlotSpec:
    return PlotSpec(f"{name}: residual RMS vs threshold, true fault", ("channels", "actuator"),
                    (f"+ $origin/{i}/{name}/rms", f"+ $origin/{i}/{name}/threshold",
                     f"+ $origin/{i}/{name}/true_fault"))


def _servo(k: int, name: str) -> PlotSpec:
    """The servo tier's channels of one surface (ChannelId("surface", k, ...)): reconstructed
    input and output faults, their RMS against the thresholds, the true fault."""
    return PlotSpec(f"{name} servo: faults, RMS vs threshold", ("channels", "surface", k),
                    ("+ $origin/**",))


def views(cfg: ActuatorFamilyConfig) -> FamilyViews:
    """Aircraft level: positions and effectiveness in one column, one residual plot per
    actuator; servo level: one plot per surface."""
    rms = tuple(_rms(i, n) for i, n in enumerate(ACTUATORS))
    columns = (("Actuators", (_positions(), _effectiveness())),
               ("Surfaces", rms[:len(SURFACES)]), ("Engine", rms[len(SURFACES):]),
               ("Servo level", tuple(_servo(k, n) for k, n in enumerate(SURFACES))))
    return FamilyViews("Actuators", columns, overview=(_positions(),))
