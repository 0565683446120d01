"""Alarm events: what the FDI layer emits and every sink publishes (schema in docs/alarms.md)."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum

from gcs_monitor.core.types import ChannelId


class AlarmState(StrEnum):
    RAISED = "raised"
    UPDATED = "updated"
    CLEARED = "cleared"


class AlarmKind(StrEnum):
    SENSOR_FAULT = "sensor_fault"
    ACTUATOR_FAULT = "actuator_fault"
    SET_LOST = "set_lost"  # every instance of a redundant set is faulty (Wan2018 Table I)
    LINK = "link"  # link problems: never reported as a sensor fault
    ESTIMATOR = "estimator"  # estimator numerics / unavailable inputs
    # a family judged too little of the recent flight (fdi.coverage); never a sensor fault
    MONITOR_DEGRADED = "monitor_degraded"


class FaultType(StrEnum):
    UNKNOWN = "unknown"
    BIAS = "bias"
    DRIFT = "drift"
    OSCILLATION = "oscillation"
    STUCK = "stuck"
    RUNAWAY = "runaway"
    # an actuator that still moves but acts less (part of a surface, or thrust, lost); the
    # magnitude is the share of the effect lost, 1 for an engine out
    LOSS_OF_EFFECTIVENESS = "loss_of_effectiveness"
    NOISE = "noise"
    LINK = "link"
    NO_DATA = "no_data"  # an instance of a redundant set stopped delivering valid values


OBSERVED_TYPES = frozenset({FaultType.NO_DATA, FaultType.LINK})
"""Fault types that are observations, not shape classifications (confidence 1)."""


@dataclass(frozen=True, slots=True)
class AlarmEvent:
    """One alarm transition (raised / updated / cleared) on one channel.

    Attributes
    ----------
    t_us : vehicle time of the transition (int µs); sinks add wall time
    channel : isolated channel (kind, instance, axis)
    magnitude : estimated fault magnitude in the channel's SI unit (signed, NaN if unknown)
    residual_rms : residual RMS J at the transition (Wan2018 eq. 18), SI
    threshold : J_th used, SI
    estimator : which estimator's residual raised it (``"voting"`` for the set-level reference)
    confidence : confidence in ``fault_type``, in [0, 1]: the classifier's margin for an
        inferred type (bias, drift, ...; :mod:`gcs_monitor.fdi.classify`), 1 for an observed
        one (link, no_data), 0 for unknown
    alarm_id : the stable id of the alarm this transition belongs to (the same on its raise,
        updates and clear), given by the monitor from vehicle, channel and raise time; ``""``
        until then. Not part of equality: the FDI layer's events compare as before
    """

    t_us: int
    channel: ChannelId
    state: AlarmState
    kind: AlarmKind
    fault_type: FaultType
    magnitude: float
    residual_rms: float
    threshold: float
    estimator: str
    message: str = ""
    vehicle: int = 1
    confidence: float = 0.0
    alarm_id: str = field(default="", compare=False)


@dataclass(frozen=True, slots=True)
class SetStatus:
    """Per-sample state of one redundant set (triplex AoA, triplex CAS, IMU axes) for the sinks.

    measured/rms/weights/faulty are (n,) per instance; fused is the adaptive weighted value
    (Wan2018 eq. 19); configuration names the output configuration (Wan2018 Table I).
    """

    name: str  # e.g. "aoa", "cas"
    t_us: int
    measured: tuple[float, ...]
    reference: float  # what residuals are taken against (model prediction or fused value)
    fused: float
    weights: tuple[float, ...]
    rms: tuple[float, ...]
    threshold: float
    faulty: tuple[bool, ...]
    configuration: str


@dataclass(frozen=True, slots=True)
class ChannelStatus:
    """Per-sample state of one estimator channel (e.g. reconstructed accelerometer fault f_Ax)."""

    channel: ChannelId
    t_us: int
    value: float  # the monitored signal (fault estimate or residual), SI
    rms: float
    threshold: float
    faulty: bool
    estimator: str


SET_INSTANCE = -1
"""ChannelId.instance used for set-level alarms (SET_LOST) of a redundant set."""
