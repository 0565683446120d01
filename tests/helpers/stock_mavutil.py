"""Stock ``pymavlink.mavutil`` as a fresh process without MAVLINK20 / MAVLINK_DIALECT sees it.

Tests use it as an independent reader of what the simulator and the converters write: it must
read MAVLink 2 / ardupilotmega output with no configuration (it upgrades to MAVLink 2 on the first
v2 packet). mavutil writes both variables into ``os.environ`` (at import and on that upgrade);
:func:`stock_mavutil` puts the environment back afterwards so no other test inherits them.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from types import ModuleType

_MAVUTIL_ENV = ("MAVLINK20", "MAVLINK_DIALECT")


@contextmanager
def stock_mavutil() -> Iterator[ModuleType]:
    saved = dict(os.environ)
    for k in _MAVUTIL_ENV:
        os.environ.pop(k, None)
    try:
        from pymavlink import mavutil

        mavutil.set_dialect("all")  # mavutil's default, MAVLink 1 until a v2 packet arrives
        yield mavutil
    finally:
        os.environ.clear()
        os.environ.update(saved)
