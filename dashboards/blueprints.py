"""Rerun blueprints built from the families' dashboard declarations.

Each family declares its views as plain data (:class:`gcs_monitor.families.base.FamilyViews`:
a tab of plot columns and the plots it adds to the overview); this module turns them into a
Rerun blueprint. Paths follow :func:`gcs_monitor.sinks.rerun_sink.entity_path`; the application
id is :data:`gcs_monitor.sinks.rerun_sink.APPLICATION_ID` (``rr.init``/``RecordingStream`` must
use it for the viewer to apply the blueprint).
"""

from __future__ import annotations

from collections.abc import Sequence

import rerun.blueprint as rrb

from gcs_monitor.config import MonitorConfig
from gcs_monitor.families import registry
from gcs_monitor.families.base import FamilyViews, PlotSpec
from gcs_monitor.sinks.rerun_sink import APPLICATION_ID, TIMELINE, entity_path

__all__ = [
    "APPLICATION_ID",
    "alarms_view",
    "attitude_view",
    "default_blueprint",
    "family_tab",
    "family_views",
    "overview",
]


def family_views(cfg: MonitorConfig | None = None) -> list[FamilyViews]:
    """The dashboards of the families ``cfg`` enables (default: the default configuration)."""
    c = cfg if cfg is not None else MonitorConfig()
    return [spec.views(c.families[spec.name]) for spec in registry.FAMILIES
            if spec.name in c.families and c.families[spec.name].enabled]


def plot(vehicle: int, spec: PlotSpec) -> rrb.TimeSeriesView:
    """One declared time-series plot of ``vehicle``."""
    origin = entity_path(vehicle, *spec.origin)
    if spec.contents:
        return rrb.TimeSeriesView(name=spec.name, origin=origin, contents=list(spec.contents))
    return rrb.TimeSeriesView(name=spec.name, origin=origin)


def family_tab(vehicle: int, views: FamilyViews) -> rrb.Container:
    """A family's tab: its columns of stacked plots side by side."""
    return rrb.Horizontal(
        *(rrb.Vertical(*(plot(vehicle, p) for p in plots), name=name)
          for name, plots in views.columns),
        name=views.tab)


def coverage_view(vehicle: int) -> rrb.TimeSeriesView:
    """Each family's share of the last window judged (monitor_degraded below 90 %)."""
    return rrb.TimeSeriesView(name="Coverage: share of the last 10 s judged",
                              origin=entity_path(vehicle, "coverage"))


def overview(vehicle: int, views: Sequence[FamilyViews]) -> rrb.Container:
    """One screen of the must-show plots: every family's overview plots in a grid, and the
    families' coverage."""
    return rrb.Grid(*(plot(vehicle, p) for v in views for p in v.overview),
                    coverage_view(vehicle), grid_columns=2, name="Overview")


def alarms_view(vehicle: int) -> rrb.TextLogView:
    """The alarm log (raised = WARN / ERROR for a lost set, cleared = INFO)."""
    return rrb.TextLogView(name="Alarms", origin=entity_path(vehicle, "alarms"))


def attitude_view(vehicle: int) -> rrb.Spatial3DView:
    """Local NED track and the attitude box/body axes."""
    return rrb.Spatial3DView(name="Track and attitude", origin=entity_path(vehicle, "world"))


def default_blueprint(vehicle: int, views: Sequence[FamilyViews] | None = None) -> rrb.Blueprint:
    """Overview and one tab per family on the left, 3-D view and alarm log on the right;
    ``views`` default to those of the default configuration."""
    fv = family_views() if views is None else list(views)
    # the overview reads best with the air-data plots first (the set the demo flies)
    ordered = sorted(fv, key=lambda v: v.tab != "Air data")
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Tabs(overview(vehicle, ordered), *(family_tab(vehicle, v) for v in ordered),
                     name="Fault families"),
            rrb.Vertical(attitude_view(vehicle), alarms_view(vehicle), row_shares=[3, 2]),
            column_shares=[3, 2],
        ),
        # "following" puts the time cursor at the newest data, so a finished .rrd opens at its end
        # (all alarms visible) and a live stream keeps up.
        rrb.TimePanel(timeline=TIMELINE, state="collapsed", play_state="following"),
        collapse_panels=True,
    )
