"""The one pymavlink import: the MAVLink 2 ``ardupilotmega`` dialect module, imported directly.

Not through ``mavutil``: nothing here reads or sets ``MAVLINK20`` / ``MAVLINK_DIALECT``, so the
monitor decodes MAVLink 2 (and AOA_SSA, an ardupilotmega message) whatever the environment holds.
"""

from __future__ import annotations

from pymavlink.dialects.v20 import ardupilotmega as mavlink

__all__ = ["mavlink"]
