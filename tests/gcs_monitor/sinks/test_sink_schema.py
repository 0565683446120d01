"""Schema round trips and the JSON contract of docs/alarms.md."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from gcs_monitor.core.types import ChannelId
from gcs_monitor.fdi.events import AlarmEvent, AlarmKind, AlarmState, FaultType
from gcs_monitor.fdi.records import Estimate
from gcs_monitor.sinks.schema import (
    SCHEMA_VERSION,
    alarm_from_dict,
    alarm_to_dict,
    dumps,
    estimate_from_dict,
    estimate_to_dict,
    health_to_dict,
)

WALL_S = 1_700_000_000.25  # 2023-11-14T22:13:20.250Z


def _event(**kw: object) -> AlarmEvent:
    base = dict(
        t_us=12_340_000,
        channel=ChannelId("aoa", 2),
        state=AlarmState.RAISED,
        kind=AlarmKind.SENSOR_FAULT,
        fault_type=FaultType.BIAS,
        magnitude=0.0349,
        residual_rms=0.021,
        threshold=0.014,
        estimator="voting",
        message="vane 2",
        vehicle=3,
        confidence=0.75,
    )
    base.update(kw)
    return AlarmEvent(**base)  # type: ignore[arg-type]


def test_alarm_payload_keys_and_values() -> None:
    d = alarm_to_dict(_event(), wall_time_s=WALL_S)
    assert d["schema_version"] == SCHEMA_VERSION == 2
    assert d["confidence"] == 0.75
    assert d["type"] == "alarm"
    assert d["vehicle"] == 3
    assert d["channel"] == {"kind": "aoa", "instance": 2, "axis": ""}
    assert d["channel_name"] == "aoa2"
    assert (d["state"], d["kind"], d["fault_type"]) == ("raised", "sensor_fault", "bias")
    assert d["unit"] == "rad"
    assert d["vehicle_time_s"] == pytest.approx(12.34)  # 12_340_000 us
    assert d["wall_time"] == "2023-11-14T22:13:20.250Z"
    assert d["estimator"] == "voting"


def test_alarm_round_trip_through_json() -> None:
    ev = _event(channel=ChannelId("acc", 1, "z"), state=AlarmState.CLEARED)
    back = alarm_from_dict(json.loads(dumps(alarm_to_dict(ev, wall_time_s=WALL_S))))
    assert back == ev


def test_nan_becomes_null_and_back() -> None:
    ev = _event(magnitude=float("nan"))
    text = dumps(alarm_to_dict(ev, wall_time_s=WALL_S))
    assert "NaN" not in text and '"magnitude":null' in text
    assert math.isnan(alarm_from_dict(json.loads(text)).magnitude)


@given(
    t_us=st.integers(0, 2**62),
    inst=st.integers(0, 7),
    mag=st.floats(allow_nan=False, allow_infinity=False, width=64),
    state=st.sampled_from(list(AlarmState)),
    kind=st.sampled_from(list(AlarmKind)),
    ftype=st.sampled_from(list(FaultType)),
)
def test_alarm_round_trip_property(
    t_us: int, inst: int, mag: float, state: AlarmState, kind: AlarmKind, ftype: FaultType
) -> None:
    ev = _event(
        t_us=t_us,
        channel=ChannelId("gyro", inst, "r"),
        magnitude=mag,
        state=state,
        kind=kind,
        fault_type=ftype,
    )
    assert alarm_from_dict(json.loads(dumps(alarm_to_dict(ev, wall_time_s=WALL_S)))) == ev


def test_schema_1_alarm_is_read_without_confidence() -> None:
    d = alarm_to_dict(_event(), wall_time_s=WALL_S)
    d["schema_version"] = 1
    del d["confidence"]
    back = alarm_from_dict(d)
    assert math.isnan(back.confidence) and back.fault_type is FaultType.BIAS


def test_newer_schema_rejected() -> None:
    d = alarm_to_dict(_event(), wall_time_s=WALL_S)
    d["schema_version"] = SCHEMA_VERSION + 1
    with pytest.raises(ValueError, match="schema_version"):
        alarm_from_dict(d)
    d["schema_version"] = SCHEMA_VERSION
    d["type"] = "estimate"
    with pytest.raises(ValueError, match="type"):
        alarm_from_dict(d)


def test_estimate_round_trip() -> None:
    ch = ChannelId("acc", 0, "x")
    est = Estimate(
        name="imu_ts",
        t_us=5_000_000,
        states={
            "vel_ned_mps": np.array([25.0, -1.5, 0.25]),
            "wind_ned_mps": np.array([np.nan, 1.0, 0.0]),
        },
        faults={ch: 0.5},
        residuals={ch: -0.01},
        virtual={ch: 0.3},
        numerics_ok=False,
    )
    d = json.loads(dumps(estimate_to_dict(est, vehicle=2, wall_time_s=WALL_S)))
    assert d["states"]["wind_ned_mps"][0] is None
    back = estimate_from_dict(d)
    assert back.name == est.name and back.t_us == est.t_us and back.numerics_ok is False
    np.testing.assert_array_equal(back.states["vel_ned_mps"], est.states["vel_ned_mps"])
    assert math.isnan(back.states["wind_ned_mps"][0])
    assert back.faults == {ch: 0.5} and back.residuals == {ch: -0.01} and back.virtual == {ch: 0.3}


def test_health_is_json_with_numpy_and_nan() -> None:
    h = {
        "link": {"loss": np.float64(0.02), "rates_hz": np.array([100.0, 10.0])},
        "alarms": [_event()],
        "gps_age_s": float("inf"),
        "ok": np.bool_(True),
    }
    d = json.loads(dumps(health_to_dict(h, vehicle=1, wall_time_s=WALL_S)))
    assert d["type"] == "health" and d["schema_version"] == SCHEMA_VERSION
    assert d["health"]["link"] == {"loss": 0.02, "rates_hz": [100.0, 10.0]}
    assert d["health"]["gps_age_s"] is None and d["health"]["ok"] is True
    assert d["health"]["alarms"][0]["channel_name"] == "aoa2"
