"""The one pymavlink import: MAVLink 2, ardupilotmega dialect, chosen before import."""

from __future__ import annotations

import os

os.environ["MAVLINK20"] = "1"
os.environ.setdefault("MAVLINK_DIALECT", "ardupilotmega")

from pymavlink.dialects.v20 import ardupilotmega as mavlink  # noqa: E402

__all__ = ["mavlink"]
