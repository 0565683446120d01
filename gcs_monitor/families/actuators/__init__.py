"""Actuator family: control surfaces and engine judged from servo outputs, setpoints and the
aircraft's response (aircraft tier, RLS per axis as Keipour 2019), composed with the Lu2017
servo tier where surface feedback exists."""

from gcs_monitor.families.actuators.config import ActuatorFamilyConfig
from gcs_monitor.families.actuators.family import RATE_HZ, ActuatorFamily
from gcs_monitor.families.actuators.views import views
from gcs_monitor.families.base import FamilySpec

SPEC = FamilySpec(
    name="actuators",
    title="actuators (Lu2017 servo level; aircraft level: RLS per axis, Keipour 2019)",
    config=ActuatorFamilyConfig,
    build=ActuatorFamily,
    inputs=(("imu_instances", "IMU"), ("attitude", "attitude"),
            ("commands", "servo outputs or setpoints")),
    rate_hz=RATE_HZ,
    views=views,
)

__all__ = ["SPEC", "ActuatorFamily", "ActuatorFamilyConfig"]
