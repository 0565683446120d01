"""The catalogue of sensor channels: names, the sensor group that samples them, their dimension.

Channel names are what a scenario's ``[[faults]] channel = ...`` refers to, e.g. ``imu0.acc.x``,
``imu2.gyro.r``, ``attitude.phi``, ``gps.vel.n``, ``gps.lat``, ``baro.alt``, ``baro.vs``,
``aoa1``, ``cas2``, ``ssa``, ``static.p``, ``oat``.
"""

from __future__ import annotations

from dataclasses import dataclass

N_AIRDATA = 3  # triplex AoA vanes and pitot-static CAS (Wan2018 sec. II)
MAX_IMU = 3


@dataclass(frozen=True, slots=True)
class ChannelInfo:
    name: str
    group: str  # sensor group (one noise generator, one rate) e.g. "imu0", "airdata"
    index: int  # position in the group's measurement vector
    dimension: str  # key of sim_vehicle.faults.units.UNITS


def group_channels(group: str) -> list[tuple[str, str]]:
    """(channel name, dimension) of one sensor group, in measurement-vector order."""
    if group.startswith("imu"):
        return [(f"{group}.acc.{a}", "acc") for a in "xyz"] + [
            (f"{group}.gyro.{a}", "angrate") for a in "pqr"
        ]
    if group == "attitude":
        return [(f"attitude.{a}", "angle") for a in ("phi", "theta", "psi")]
    if group == "gps":
        return [(f"gps.vel.{a}", "speed") for a in "ned"] + [
            ("gps.lat", "angle"),
            ("gps.lon", "angle"),
            ("gps.alt", "length"),
        ]
    if group == "baro":
        return [("baro.alt", "length"), ("baro.vs", "speed")]
    if group == "airdata":
        return (
            [(f"aoa{i}", "angle") for i in range(N_AIRDATA)]
            + [(f"cas{i}", "speed") for i in range(N_AIRDATA)]
            + [("ssa", "angle")]
        )
    if group == "static":
        return [("static.p", "pressure"), ("oat", "temperature")]
    raise KeyError(group)


def sensor_groups(n_imu: int) -> list[str]:
    return [f"imu{i}" for i in range(n_imu)] + ["attitude", "gps", "baro", "airdata", "static"]


def channel_catalogue(n_imu: int) -> dict[str, ChannelInfo]:
    """Every channel that exists with ``n_imu`` IMUs, by name."""
    out: dict[str, ChannelInfo] = {}
    for g in sensor_groups(n_imu):
        for i, (name, dim) in enumerate(group_channels(g)):
            out[name] = ChannelInfo(name, g, i, dim)
    return out
