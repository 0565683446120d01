"""FDI performance metrics of Wan2018 sec. VI-B (Table IV), as pure functions.

Definitions (Wan2018 sec. VI-B, per sensor group such as AoA or CAS):

- FAR, false alarm rate: percentage of fault-free runs in which a fault is (incorrectly)
  detected;
- MDR, missed detection rate: percentage of faulty runs in which at least one faulty
  sensor is not detected;
- FIR, false isolation rate: percentage of faulty runs in which at least one healthy
  sensor is incorrectly identified as faulty;
- DetD max / mean: max and mean over runs of ``t_detect - t_fault``.

How they are read here (the paper gives no more detail):

- a detection is a RAISED event of kind SENSOR_FAULT or ACTUATOR_FAULT on the channel;
  LINK, ESTIMATOR and SET_LOST events never count (SET_LOST accompanies per-instance
  alarms which are counted themselves);
- a RAISED on channel c at time t is correct when c is faulty at t, i.e. t lies in one of
  c's ground-truth intervals ``[start, end + grace_us]`` (``end`` None = until the end of
  the run; the grace lets a latched alarm raised just after the fault ended count);
  any other RAISED is a false alarm (fault-free run) or a false isolation (faulty run);
- a faulty channel is detected when a correct RAISED exists for each of its intervals;
- the run's detection delay is the largest delay over its detected faulty channels (the
  time until the whole fault set of the run has been detected; with one faulty sensor it
  is that sensor's delay), in seconds.  Runs with a missed fault contribute the delays of
  the faults that were detected.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass

from gcs_monitor.core.types import ChannelId
from gcs_monitor.fdi.events import AlarmEvent, AlarmKind, AlarmState

FaultIntervals = Mapping[ChannelId, Sequence[tuple[int, int | None]]]
_US_PER_S = 1e6
_COUNTED = (AlarmKind.SENSOR_FAULT, AlarmKind.ACTUATOR_FAULT)


@dataclass(frozen=True, slots=True)
class RunOutcome:
    """FDI outcome of one run for one sensor group."""

    group: str
    faulty_run: bool
    false_alarm: bool  # fault-free run with any detection
    missed: bool  # faulty run with an undetected fault
    false_isolation: bool  # faulty run with a healthy channel raised
    delay_s: float  # NaN when nothing was detected or the run is fault-free


@dataclass(frozen=True, slots=True)
class MetricsRow:
    """One row of Wan2018 Table IV."""

    group: str
    n_fault_free: int
    n_faulty: int
    far_pct: float
    mdr_pct: float
    fir_pct: float
    delay_max_s: float
    delay_mean_s: float


def _group_of(ch: ChannelId) -> str:
    return ch.kind


def _in_interval(t: int, iv: tuple[int, int | None], grace_us: int) -> bool:
    start, end = iv
    return t >= start and (end is None or t <= end + grace_us)


def evaluate_run(
    events: Iterable[AlarmEvent],
    truth: FaultIntervals,
    *,
    groups: Iterable[str] = (),
    grace_us: int = 0,
    group_of: Callable[[ChannelId], str] = _group_of,
) -> dict[str, RunOutcome]:
    """Outcome of one run per sensor group.

    Parameters
    ----------
    events : every alarm event of the run
    truth : ground-truth fault intervals per channel, vehicle time µs
    groups : groups to report even when no event or fault touches them (fault-free runs)
    grace_us : tolerance after a fault interval's end, µs
    group_of : maps a channel to its group (default: ``channel.kind``)
    """
    raised = [e for e in events if e.state is AlarmState.RAISED and e.kind in _COUNTED]
    all_groups = set(groups) | {group_of(c) for c in truth if truth[c]}
    all_groups |= {group_of(e.channel) for e in raised}
    out: dict[str, RunOutcome] = {}
    for g in sorted(all_groups):
        g_truth = {c: list(iv) for c, iv in truth.items() if group_of(c) == g and iv}
        g_raised = [e for e in raised if group_of(e.channel) == g]
        faulty_run = bool(g_truth)
        wrong = False
        for e in g_raised:
            ivs = g_truth.get(e.channel, [])
            if not any(_in_interval(e.t_us, iv, grace_us) for iv in ivs):
                wrong = True
        missed = False
        delays: list[float] = []
        for c, ivs in g_truth.items():
            times = sorted(e.t_us for e in g_raised if e.channel == c)
            for iv in ivs:
                hit = next((t for t in times if _in_interval(t, iv, grace_us)), None)
                if hit is None:
                    missed = True
                else:
                    delays.append((hit - iv[0]) / _US_PER_S)
        out[g] = RunOutcome(
            group=g,
            faulty_run=faulty_run,
            false_alarm=wrong and not faulty_run,
            missed=missed,
            false_isolation=wrong and faulty_run,
            delay_s=max(delays) if delays else math.nan,
        )
    return out


def _pct(k: int, n: int) -> float:
    return 100.0 * k / n if n else math.nan


def metrics_table(runs: Sequence[Mapping[str, RunOutcome]]) -> list[MetricsRow]:
    """Aggregate run outcomes into Wan2018 Table IV rows, one per group (sorted)."""
    by_group: dict[str, list[RunOutcome]] = {}
    for run in runs:
        for g, o in run.items():
            by_group.setdefault(g, []).append(o)
    rows = []
    for g in sorted(by_group):
        os_ = by_group[g]
        free = [o for o in os_ if not o.faulty_run]
        faulty = [o for o in os_ if o.faulty_run]
        d = [o.delay_s for o in faulty if math.isfinite(o.delay_s)]
        rows.append(MetricsRow(
            group=g,
            n_fault_free=len(free),
            n_faulty=len(faulty),
            far_pct=_pct(sum(o.false_alarm for o in free), len(free)),
            mdr_pct=_pct(sum(o.missed for o in faulty), len(faulty)),
            fir_pct=_pct(sum(o.false_isolation for o in faulty), len(faulty)),
            delay_max_s=max(d) if d else math.nan,
            delay_mean_s=math.fsum(d) / len(d) if d else math.nan,
        ))
    return rows


def format_table(rows: Sequence[MetricsRow]) -> str:
    """Markdown table in the layout of Wan2018 Table IV."""
    lines = ["| group | fault-free runs | faulty runs | FAR [%] | MDR [%] | FIR [%] "
             "| DetD max [s] | DetD mean [s] |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r.group} | {r.n_fault_free} | {r.n_faulty} | {r.far_pct:.2f} "
                     f"| {r.mdr_pct:.2f} | {r.fir_pct:.2f} | {r.delay_max_s:.2f} "
                     f"| {r.delay_mean_s:.2f} |")
    return "\n".join(lines)
