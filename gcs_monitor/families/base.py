"""What a monitored family is: the protocol the pipeline drives and the registry entry.

A family (``imu``, ``airdata``, ...) owns its estimators, its FDI sets and channel kinds, its
configuration section, the telemetry it needs and the rates it is valid for, and its dashboard
views. Per Frame the pipeline runs every configured family through the same three phases
(design.md, "The flow of data"):

1. ``predict(frame)``: the estimators' view of this sample before its measurements are judged
   (Wan2018 eq. 17 needs ``y_hat_{k|k-1}`` *before* the update; a fault-reconstructing filter
   such as Lu2016's two-stage EKF gives its reconstructed faults here);
2. ``judge(frame, prediction)``: the family's FDI sets and channels window, confirm, isolate,
   fuse and classify (``gcs_monitor.fdi``), giving alarm events, statuses, the fused values and
   the family's own :class:`~gcs_monitor.fdi.records.FamilyStatus` (did it judge, why not);
3. ``update(frame, verdict)``: the estimators take what the vote kept (Wan2018 eq. 19 fusion
   as the MHE's measurement) and return their :class:`~gcs_monitor.fdi.records.Estimate`\\ s.

A new family is a new package under ``gcs_monitor/families/`` exposing a :class:`FamilySpec`
and one line in :mod:`gcs_monitor.families.registry`; nothing else in the pipeline changes.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

from gcs_monitor.fdi.alarms import AlarmParams
from gcs_monitor.fdi.classify import ClassifierShape
from gcs_monitor.fdi.events import AlarmEvent, ChannelStatus, SetStatus
from gcs_monitor.fdi.records import Estimate, FamilyStatus
from gcs_monitor.telemetry.frame import Frame


class FaultEstimator(Protocol):
    """An estimator that reconstructs faults (Lu2016, Atmaca2025): one step per Frame gives the
    fault estimates the family's FDI channels judge."""

    name: str

    def step(self, frame: Frame) -> Estimate: ...

    def reset(self) -> None: ...


@dataclass
class Verdict:
    """What a family's FDI decided on one Frame.

    Attributes
    ----------
    status : whether the family judged this Frame, and why not
    events : alarm transitions (raised / updated / cleared) and operator notices
    sets : redundant-set statuses (Wan2018 eq. 18-19, Table I) judged on this Frame
    channels : per-channel statuses (reconstructed faults against their thresholds)
    fused : per redundant set, the value the estimators may take as their measurement
        (Wan2018 eq. 19); None when no instance of the set is healthy
    """

    status: FamilyStatus
    events: list[AlarmEvent] = field(default_factory=list)
    sets: list[SetStatus] = field(default_factory=list)
    channels: list[ChannelStatus] = field(default_factory=list)
    fused: dict[str, float | None] = field(default_factory=dict)


class Family(Protocol):
    """One monitored family of one vehicle (see the module docstring for the three phases)."""

    name: str

    def predict(self, frame: Frame) -> Any: ...

    def judge(self, frame: Frame, prediction: Any) -> Verdict: ...

    def update(self, frame: Frame, verdict: Verdict) -> list[Estimate]: ...


AIRSPEED_CAS = "airdata.cas_mps"
"""Blackboard key: the air-data family's airspeed (CAS, m/s) for the families after it."""
FUSED = "fused"
"""Source of a shared value: the vote of the healthy instances (Wan2018 eq. 19)."""
VIRTUAL = "virtual"
"""Source of a shared value: an estimator's virtual sensor while no instance is healthy (Wan2018
Table I); good for a scale, not for judging another sensor by (a reader decides)."""


@dataclass(frozen=True, slots=True)
class SharedValue:
    """One value a family published for the families after it: what, when, and from what
    (:data:`FUSED`, :data:`VIRTUAL`; a withdrawal, NaN, says why there is none).

    ``survivor`` marks a fused value that is the one instance left of a set that has lost the
    others: no vote checks it any more, and what took the others (icing, a blocked drain) may
    be on it too. It is still the best measurement there is; a reader that judges something
    else *by* it (the aircraft tier's thrust against drag) may decline it."""

    value: float
    t_us: int
    source: str
    survivor: bool = False


class Blackboard:
    """What the families of one vehicle tell each other within a Frame.

    A family that judges a redundant set knows better than a family that merely reads it which
    instances to trust: the yaw-rate observer schedules on airspeed, and when two pitots of
    three are faulty their median is wrong while the air-data family's fused value is not;
    when all are faulty that family says so (its virtual sensor, marked as such). The
    pipeline runs the families in registry order, so a value put here on a Frame is read by
    the families after its writer on the same Frame. A reader falls back to its own reading of
    the raw instances when nothing (fresh) is here: the writer is disabled, or has not judged
    yet.
    """

    __slots__ = ("_values",)

    def __init__(self) -> None:
        self._values: dict[str, SharedValue] = {}

    def put(self, key: str, value: float, t_us: int, source: str, *,
            survivor: bool = False) -> None:
        self._values[key] = SharedValue(value, t_us, source, survivor)

    def withdraw(self, key: str, t_us: int, source: str) -> None:
        """The writer judged and has no value (every instance faulty, no estimator): readers
        must not fall back to the raw instances."""
        self._values[key] = SharedValue(float("nan"), t_us, source)

    def get(self, key: str, t_us: int, max_age_s: float) -> SharedValue | None:
        """The latest value of ``key`` if it is at most ``max_age_s`` old at ``t_us``."""
        v = self._values.get(key)
        if v is None or (t_us - v.t_us) > max_age_s * 1e6:
            return None
        return v


@dataclass(frozen=True, slots=True)
class FamilyContext:
    """What a family needs to know about where it runs.

    vehicle : MAVLink sysid stamped on its alarm events
    stale_after_s : an input older than this is invalid (``[telemetry] stale_after_s``)
    statuses : build per-channel status records, and the estimates that only sinks and
        callbacks read (off when no sink or callback reads them; alarms are the same either way)
    alarm : alarm update policy (``[alarms]``)
    classifier : the classifier's shape tests (``[classifier]``)
    shared : the vehicle's blackboard, one object for all its families (values one family
        gives the families after it within a Frame)
    """

    vehicle: int
    stale_after_s: float
    statuses: bool = True
    alarm: AlarmParams = field(default_factory=AlarmParams)
    classifier: ClassifierShape = field(default_factory=ClassifierShape)
    shared: Blackboard = field(default_factory=Blackboard, compare=False)


@dataclass(frozen=True, slots=True)
class PlotSpec:
    """One time-series plot of a dashboard: a title, an entity origin below the vehicle
    (``("sets", "aoa")``), and entity filters relative to it (Rerun's ``+ $origin/...``)."""

    name: str
    origin: tuple[str | int, ...]
    contents: tuple[str, ...] = ()


@dataclass(frozen=True, slots=True)
class FamilyViews:
    """A family's dashboard: a tab of plot columns and the plots it adds to the overview.

    Pure data: ``dashboards/`` turns it into a Rerun blueprint (only sinks and dashboards
    import rerun)."""

    tab: str
    columns: tuple[tuple[str, tuple[PlotSpec, ...]], ...]
    overview: tuple[PlotSpec, ...] = ()


@dataclass(frozen=True, slots=True)
class FamilySpec:
    """A family's registry entry.

    Attributes
    ----------
    name : registry key and TOML section (``[imu]``)
    title : what an operator reads (papers included)
    config : the family's configuration dataclass (its defaults run with no file); it has an
        ``enabled`` field
    build : ``build(config, context)`` makes the family for one vehicle
    inputs : the telemetry it needs, as (availability key, what an operator reads) pairs; the
        keys are those of :meth:`gcs_monitor.telemetry.assembler.FrameAssembler.availability`
        (a count > 0 or True means present)
    rate_hz : the rates of its driving stream it is valid for (min, max)
    views : ``views(config)`` gives its dashboard
    """

    name: str
    title: str
    config: type
    build: Callable[[Any, FamilyContext], Family]
    inputs: tuple[tuple[str, str], ...]
    rate_hz: tuple[float, float]
    views: Callable[[Any], FamilyViews]

    def missing_inputs(self, availability: dict[str, Any]) -> list[str]:
        """The operator names of the inputs this vehicle's telemetry does not carry."""
        return [what for key, what in self.inputs if not availability.get(key)]


def enabled_families(specs: Sequence[FamilySpec], configs: dict[str, Any]) -> list[FamilySpec]:
    """The registered families whose configuration enables them, in registry order."""
    return [s for s in specs if getattr(configs[s.name], "enabled", False)]
