"""What a family's estimators give the FDI layer, and what one Frame produced, for the sinks.

:class:`Estimate` is an estimator's output at one instant (state, reconstructed faults,
residuals, virtual sensors); :class:`FamilyStatus` is a family's own account of whether it
judged the sample and why not (the coverage the design asks every family to report, in the
spirit of PX4 EKF2's aid-source status); :class:`StepOutput` gathers everything one Frame
produced -- alarm events, estimates, redundant-set and channel statuses, family statuses -- and
is what the sinks publish. Plain data, no behaviour.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from gcs_monitor.core.types import ChannelId, Vec
from gcs_monitor.fdi.events import AlarmEvent, ChannelStatus, SetStatus


@dataclass(frozen=True, slots=True)
class Estimate:
    """What one estimator says at one instant.

    Attributes
    ----------
    name : estimator name (``"imu_ts"``, ``"airdata_cmhe"``, ...)
    t_us : vehicle time (int µs)
    available : False when inputs were missing; ``reason`` says which
    states : named state estimates (SI), e.g. ``{"vel_ned_mps": (3,), "euler_rad": (3,)}``
    faults : reconstructed faults per channel (SI), e.g. ``{ChannelId("acc",0,"x"): 3.0}``
    residuals : residuals per monitored channel (measurement minus prediction, SI)
    virtual : corrected / virtual-sensor values per channel (SI)
    numerics_ok : False if the filter detected a numerical failure (and reset itself)
    reinit : non-empty when the estimator (re)initialised states at this instant; says why
        (start, input gap, rejected velocity step); the FDI does not judge the fault channels
        for ``reinit_warmup_s`` afterwards and tells the operator (an ESTIMATOR event, never a
        sensor-fault alarm)
    reinit_warmup_s : re-convergence time of the fault estimates after that re-initialisation
    """

    name: str
    t_us: int
    available: bool = True
    reason: str = ""
    states: dict[str, Vec] = field(default_factory=dict)
    faults: dict[ChannelId, float] = field(default_factory=dict)
    residuals: dict[ChannelId, float] = field(default_factory=dict)
    virtual: dict[ChannelId, float] = field(default_factory=dict)
    numerics_ok: bool = True
    reinit: str = ""
    reinit_warmup_s: float = 0.0

    @staticmethod
    def unavailable(name: str, t_us: int, reason: str) -> Estimate:
        return Estimate(name=name, t_us=t_us, available=False, reason=reason)


@dataclass(frozen=True, slots=True)
class FamilyStatus:
    """One family's account of one Frame: did it judge, and if not, why.

    Attributes
    ----------
    family : registry name (``"imu"``, ``"airdata"``)
    t_us : vehicle time of the Frame
    judged : the family's FDI judged a sample of this Frame
    sample : the Frame carried a sample of the family's driving stream (air data for
        ``airdata``, the primary IMU for ``imu``); coverage counts these
    reason : why not judged (input missing or stale, warm-up, re-anchoring), ``""`` when judged
    inputs : the family's inputs are in the telemetry at all (False: a copter without vanes;
        such a family is unavailable, not degraded)
    """

    family: str
    t_us: int
    judged: bool
    sample: bool = True
    reason: str = ""
    inputs: bool = True


@dataclass(frozen=True, slots=True)
class Coverage:
    """A family's coverage (gcs_monitor.fdi.coverage).

    state : unavailable | starting | judging | degraded
    recent : share of the Frames of the last window it judged (NaN while unavailable)
    overall : the same since its inputs appeared
    reason : the most frequent reason it did not judge in the window
    """

    family: str
    state: str
    recent: float
    overall: float
    reason: str


@dataclass
class StepOutput:
    """What one Frame produced (for the sinks, tests and the evaluation harness)."""

    events: list[AlarmEvent] = field(default_factory=list)
    estimates: list[Estimate] = field(default_factory=list)
    sets: list[SetStatus] = field(default_factory=list)
    channels: list[ChannelStatus] = field(default_factory=list)
    families: list[FamilyStatus] = field(default_factory=list)
    coverage: list[Coverage] = field(default_factory=list)
