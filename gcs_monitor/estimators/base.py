"""The Estimator protocol and the Estimate every estimator returns per Frame."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from gcs_monitor.core.types import ChannelId, Vec
from gcs_monitor.telemetry.frame import Frame


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


class Estimator(Protocol):
    """A small stateful object: reads Frames, keeps its filter state, returns Estimates."""

    name: str

    def step(self, frame: Frame) -> Estimate: ...

    def reset(self) -> None: ...


def vec(*xs: float) -> Vec:
    return np.array(xs, dtype=np.float64)
