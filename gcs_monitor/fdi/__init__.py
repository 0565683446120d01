"""Fault detection and isolation: residuals -> decisions; deterministic, no clocks, no I/O.

Wan2018 sec. III-A: residual RMS windows (eq. 18), n_D-of-N_eval confirmation, adaptive
weighted fusion (eq. 19), output configurations (Table I); plus classification, alarm
state machines, link alarms, baselines and the Table IV metrics.
"""

from gcs_monitor.fdi.alarms import AlarmParams, AlarmStateMachine, LinkAlarmMonitor
from gcs_monitor.fdi.baselines import MedianVoteMonitor, MedianVoteParams
from gcs_monitor.fdi.confirmation import Confirmation, ConfirmationParams
from gcs_monitor.fdi.events import (
    SET_INSTANCE,
    AlarmEvent,
    AlarmKind,
    AlarmState,
    ChannelStatus,
    FaultType,
    SetStatus,
)
from gcs_monitor.fdi.monitor import (
    ChannelMonitor,
    ChannelMonitorParams,
    RedundantSetMonitor,
    SetMonitorParams,
    calibrate,
)
from gcs_monitor.fdi.residuals import ResidualRms, RmsWindowParams

__all__ = [
    "SET_INSTANCE", "AlarmEvent", "AlarmKind", "AlarmParams", "AlarmState", "AlarmStateMachine",
    "ChannelMonitor", "ChannelMonitorParams", "ChannelStatus", "Confirmation",
    "ConfirmationParams", "FaultType", "LinkAlarmMonitor", "MedianVoteMonitor",
    "MedianVoteParams", "RedundantSetMonitor", "ResidualRms", "RmsWindowParams", "SetStatus",
    "SetMonitorParams", "calibrate",
]
