"""IMU family: accelerometer and gyro faults reconstructed from GPS velocity and attitude
(Lu2016 ATSEKF on the GS-KM; Atmaca2025 OTSEKF + HOSM)."""

from gcs_monitor.families.base import FamilySpec
from gcs_monitor.families.imu.config import ImuFamilyConfig
from gcs_monitor.families.imu.family import RATE_HZ, ImuFamily
from gcs_monitor.families.imu.views import views

SPEC = FamilySpec(
    name="imu",
    title="IMU (Lu2016 ATSEKF, Atmaca2025 OTSEKF+HOSM)",
    config=ImuFamilyConfig,
    build=ImuFamily,
    inputs=(("imu_instances", "IMU"), ("attitude", "attitude"),
            ("gps_velocity", "GPS velocity")),
    rate_hz=RATE_HZ,
    views=views,
)

__all__ = ["SPEC", "ImuFamily", "ImuFamilyConfig"]
