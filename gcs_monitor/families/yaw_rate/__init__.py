"""Yaw-rate family: a lateral gyro's faults reconstructed by the Chen2020 LPV sliding-mode
observer on the lateral-directional dynamics (no GPS needed)."""

from gcs_monitor.families.base import FamilySpec
from gcs_monitor.families.yaw_rate.config import YawRateFamilyConfig
from gcs_monitor.families.yaw_rate.family import RATE_HZ, YawRateFamily
from gcs_monitor.families.yaw_rate.views import views

SPEC = FamilySpec(
    name="yaw_rate",
    title="yaw rate (Chen2020 LPV sliding-mode observer)",
    config=YawRateFamilyConfig,
    build=YawRateFamily,
    inputs=(("imu_instances", "IMU"), ("attitude", "attitude"), ("ssa", "sideslip"),
            ("surfaces", "surface deflections"), ("cas_instances", "airspeed")),
    rate_hz=RATE_HZ,
    views=views,
)

__all__ = ["SPEC", "YawRateFamily", "YawRateFamilyConfig"]
