"""Sinks: the only modules that import rerun or zenoh, touch files, clocks and sockets.

Every sink implements the :class:`Sink` protocol. The pipeline calls ``publish`` once per Frame
(100 Hz) per vehicle, so a sink must be cheap there: decimate plots, publish every alarm event at
once, and never block the live path (bounded queues, counted drops).

The submodules are imported lazily by their users so that ``import gcs_monitor.sinks`` stays
fast and does not load rerun or zenoh.
"""

from __future__ import annotations

from typing import Any, Protocol

from gcs_monitor.fdi.records import StepOutput
from gcs_monitor.telemetry.frame import Frame


class Sink(Protocol):
    """What the pipeline calls on every sink."""

    def publish(self, frame: Frame, out: StepOutput) -> None:
        """One Frame's worth of output (alarm events, estimates, set and channel statuses,
        family statuses); called at the Frame rate (100 Hz)."""
        ...

    def update_health(self, health: dict[str, Any]) -> None:
        """Current alarms and link statistics (a JSON-able dict)."""
        ...

    def close(self) -> None:
        """Flush and release resources; idempotent."""
        ...


class SharedSink:
    """A sink every vehicle of a monitor shares (the journal): a vehicle's pipeline closing
    does not close it; its owner does."""

    def __init__(self, sink: Sink) -> None:
        self.sink = sink

    def publish(self, frame: Frame, out: StepOutput) -> None:
        self.sink.publish(frame, out)

    def update_health(self, health: dict[str, Any]) -> None:
        self.sink.update_health(health)

    def close(self) -> None:
        pass


__all__ = ["SharedSink", "Sink"]
