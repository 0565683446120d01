"""Rerun blueprints, one builder per fault family, plus the combined default.

Paths follow :func:`gcs_monitor.sinks.rerun_sink.entity_path`; the application id is
:data:`gcs_monitor.sinks.rerun_sink.APPLICATION_ID` (``rr.init``/``RecordingStream`` must use
it for the viewer to apply the blueprint).
"""

from __future__ import annotations

from collections.abc import Sequence

import rerun.blueprint as rrb

from gcs_monitor.sinks.rerun_sink import APPLICATION_ID, TIMELINE, entity_path

DEFAULT_SETS = ("aoa", "cas")
DEFAULT_IMU_KINDS = ("acc", "gyro")
DEFAULT_IMU_INSTANCES = (0, 1, 2)
# Rerun entity filters accept "**" only as a trailing wildcard, so per-channel leaves are listed
# explicitly (x/y/z for acc, p/q/r or x/y/z for gyro; absent entities are simply not shown).
IMU_AXES = ("x", "y", "z", "p", "q", "r")


def _imu_leaves(*leaves: str, instances: Sequence[int] = DEFAULT_IMU_INSTANCES) -> list[str]:
    return [f"+ $origin/{i}/{ax}/{leaf}" for leaf in leaves for i in instances for ax in IMU_AXES]

__all__ = [
    "APPLICATION_ID",
    "overview_views",
    "airdata_views",
    "imu_views",
    "alarms_view",
    "attitude_view",
    "default_blueprint",
]


def airdata_views(vehicle: int, sets: Sequence[str] = DEFAULT_SETS) -> rrb.Container:
    """Per redundant air-data set: measured vs fused, residual RMS vs threshold, weights."""
    columns = []
    for s in sets:
        columns.append(
            rrb.Vertical(
                rrb.TimeSeriesView(
                    name=f"{s}: measured vs fused",
                    origin=entity_path(vehicle, "sets", s),
                    contents=["+ $origin/measured/**", "+ $origin/fused", "+ $origin/reference"],
                ),
                rrb.TimeSeriesView(
                    name=f"{s}: residual RMS vs threshold",
                    origin=entity_path(vehicle, "sets", s),
                    contents=["+ $origin/rms/**", "+ $origin/threshold"],
                ),
                rrb.TimeSeriesView(
                    name=f"{s}: voting weights",
                    origin=entity_path(vehicle, "sets", s, "weight"),
                ),
                name=f"Air data {s}",
            )
        )
    return rrb.Horizontal(*columns, name="Air data")


def imu_views(vehicle: int, kinds: Sequence[str] = DEFAULT_IMU_KINDS) -> rrb.Container:
    """Per IMU kind: measured vs corrected, reconstructed vs true fault, RMS vs threshold."""
    columns = []
    for k in kinds:
        origin = entity_path(vehicle, "channels", k)
        columns.append(
            rrb.Vertical(
                rrb.TimeSeriesView(
                    name=f"{k}: measured vs corrected",
                    origin=origin,
                    contents=_imu_leaves("measured", "corrected"),
                ),
                rrb.TimeSeriesView(
                    name=f"{k}: reconstructed vs true fault",
                    origin=origin,
                    contents=_imu_leaves("fault/**", "true_fault"),
                ),
                rrb.TimeSeriesView(
                    name=f"{k}: residual RMS vs threshold",
                    origin=origin,
                    contents=_imu_leaves("rms", "threshold"),
                ),
                name=f"IMU {k}",
            )
        )
    return rrb.Horizontal(*columns, name="IMU")


def overview_views(
    vehicle: int, set_name: str = DEFAULT_SETS[0], imu_kind: str = DEFAULT_IMU_KINDS[0]
) -> rrb.Container:
    """One screen of the must-show plots: a set's measured vs fused and RMS vs threshold, an IMU
    kind's measured vs corrected and reconstructed vs true fault."""
    sets_origin = entity_path(vehicle, "sets", set_name)
    imu_origin = entity_path(vehicle, "channels", imu_kind)
    return rrb.Grid(
        rrb.TimeSeriesView(
            name=f"{set_name}: measured vs fused",
            origin=sets_origin,
            contents=["+ $origin/measured/**", "+ $origin/fused"],
        ),
        rrb.TimeSeriesView(
            name=f"{set_name}: residual RMS vs threshold",
            origin=sets_origin,
            contents=["+ $origin/rms/**", "+ $origin/threshold"],
        ),
        rrb.TimeSeriesView(
            name=f"{imu_kind}: measured vs corrected",
            origin=imu_origin,
            contents=_imu_leaves("measured", "corrected"),
        ),
        rrb.TimeSeriesView(
            name=f"{imu_kind}: reconstructed vs true fault",
            origin=imu_origin,
            contents=_imu_leaves("fault/**", "true_fault"),
        ),
        grid_columns=2,
        name="Overview",
    )


def alarms_view(vehicle: int) -> rrb.TextLogView:
    """The alarm log (raised = WARN / ERROR for a lost set, cleared = INFO)."""
    return rrb.TextLogView(name="Alarms", origin=entity_path(vehicle, "alarms"))


def attitude_view(vehicle: int) -> rrb.Spatial3DView:
    """Local NED track and the attitude box/body axes."""
    return rrb.Spatial3DView(name="Track and attitude", origin=entity_path(vehicle, "world"))


def default_blueprint(
    vehicle: int,
    *,
    sets: Sequence[str] = DEFAULT_SETS,
    imu_kinds: Sequence[str] = DEFAULT_IMU_KINDS,
) -> rrb.Blueprint:
    """Overview and per-family tabs on the left, 3-D view and alarm log on the right."""
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Tabs(
                overview_views(vehicle, sets[0], imu_kinds[0]),
                airdata_views(vehicle, sets),
                imu_views(vehicle, imu_kinds),
                name="Fault families",
            ),
            rrb.Vertical(attitude_view(vehicle), alarms_view(vehicle), row_shares=[3, 2]),
            column_shares=[3, 2],
        ),
        # "following" puts the time cursor at the newest data, so a finished .rrd opens at its end
        # (all alarms visible) and a live stream keeps up.
        rrb.TimePanel(timeline=TIMELINE, state="collapsed", play_state="following"),
        collapse_panels=True,
    )
