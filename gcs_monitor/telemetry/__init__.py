"""MAVLink messages -> SI/NED/FRD samples -> one Frame per IMU sample."""

from gcs_monitor.telemetry.frame import Frame, ImuSample

__all__ = ["Frame", "ImuSample"]
