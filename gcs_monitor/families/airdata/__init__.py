"""Air-data family: triplex angle of attack and calibrated airspeed against the Wan2018 model
(constrained MHE), residual RMS windows, adaptive fusion and output configurations."""

from gcs_monitor.families.airdata.config import AirDataFamilyConfig
from gcs_monitor.families.airdata.family import RATE_HZ, AirDataFamily
from gcs_monitor.families.airdata.views import views
from gcs_monitor.families.base import FamilySpec

SPEC = FamilySpec(
    name="airdata",
    title="air data (Wan2018 MHE, triplex AoA/CAS)",
    config=AirDataFamilyConfig,
    build=AirDataFamily,
    inputs=(("aoa_instances", "AoA"), ("cas_instances", "CAS"), ("baro", "baro"),
            ("imu_instances", "IMU"), ("attitude", "attitude"),
            ("gps_velocity", "GPS velocity")),
    rate_hz=RATE_HZ,
    views=views,
)

__all__ = ["SPEC", "AirDataFamily", "AirDataFamilyConfig"]
