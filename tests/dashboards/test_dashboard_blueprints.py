"""Blueprints: the views point at the entity paths the sink writes, and embed in an .rrd."""

from __future__ import annotations

from pathlib import Path

import rerun as rr
import rerun.blueprint as rrb
from rerun.chunk import RrdReader

from dashboards.blueprints import (
    alarms_view,
    attitude_view,
    default_blueprint,
    family_tab,
    family_views,
    overview,
)
from gcs_monitor.families.actuators.config import ActuatorFamilyConfig
from gcs_monitor.families.actuators.views import views as actuator_views
from gcs_monitor.families.airdata.config import AirDataFamilyConfig
from gcs_monitor.families.airdata.views import views as airdata_views
from gcs_monitor.families.imu.config import ImuFamilyConfig
from gcs_monitor.families.imu.views import views as imu_views
from gcs_monitor.sinks.rerun_sink import APPLICATION_ID, entity_path


def _views(c: object) -> list[object]:
    """Flatten a container tree into its views."""
    if isinstance(c, rrb.View):
        return [c]
    out: list[object] = []
    for child in getattr(c, "contents", []) or []:
        out.extend(_views(child))
    return out


def test_family_views_and_origins() -> None:
    air = _views(family_tab(5, airdata_views(AirDataFamilyConfig())))
    assert len(air) == 6  # 3 per set
    assert {v.origin for v in air} >= {entity_path(5, "sets", "aoa"), entity_path(5, "sets", "cas")}
    assert all(isinstance(v, rrb.TimeSeriesView) for v in air)
    imu = _views(family_tab(5, imu_views(ImuFamilyConfig())))
    assert len(imu) == 6 and {v.origin for v in imu} == {"/5/channels/acc", "/5/channels/gyro"}
    act = _views(family_tab(5, actuator_views(ActuatorFamilyConfig())))
    assert len(act) == 9  # positions, effectiveness, one residual per actuator, 3 servo plots
    assert {v.origin for v in act} == {"/5/estimates/actuators_aircraft", "/5/channels/actuator",
                                       "/5/channels/surface/0", "/5/channels/surface/1",
                                       "/5/channels/surface/2"}
    assert len(_views(overview(5, family_views()))) == 7  # 6 family plots + coverage
    assert isinstance(alarms_view(5), rrb.TextLogView) and alarms_view(5).origin == "/5/alarms"
    assert isinstance(attitude_view(5), rrb.Spatial3DView) and attitude_view(5).origin == "/5/world"


def test_default_blueprint_embeds_in_rrd(tmp_path: Path) -> None:
    bp = default_blueprint(2)
    p = tmp_path / "bp.rrd"
    rec = rr.RecordingStream(APPLICATION_ID, recording_id="bp-test")
    rec.save(p, default_blueprint=bp)
    rec.set_time("vehicle_time", duration=1.0)
    rec.log(entity_path(2, "sets", "aoa", "rms", 0), rr.Scalars(0.01))
    rec.disconnect()
    reader = RrdReader(p)
    bps = reader.blueprints()
    assert [b.application_id for b in bps] == [APPLICATION_ID]
    # The blueprint store holds the view origins we built (they are stored as entity paths).
    parts: list[str] = [c.entity_path for c in reader.stream(store=bps[0])]
    for c in reader.stream(store=bps[0]):
        b = c.to_record_batch()
        parts += [
            str(b.column(i).to_pylist()) for i, f in enumerate(b.schema) if "time" not in f.name
        ]
    text = " ".join(parts)
    for origin in ("/2/sets/aoa", "/2/channels/acc", "/2/alarms", "/2/world"):
        assert origin in text, origin
