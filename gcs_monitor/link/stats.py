"""Per-vehicle link statistics: counts, bytes, rates, losses from sequence gaps, errors."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any


@dataclass
class LinkStats:
    """Statistics of one vehicle (sysid) on one link.

    Sequence gaps are tracked per (sysid, compid): a forward jump of g > 1 counts g - 1 lost
    packets; a backward jump of less than half the sequence space counts a duplicate or a
    reordered packet. Two independent senders with the same sysid interleave two sequence
    streams: a high share of backward jumps, or a HEARTBEAT whose type/autopilot changes for
    the same (sysid, compid), sets ``duplicate_sysid``.
    """

    sysid: int
    messages: int = 0
    bytes: int = 0
    per_type: dict[str, int] = field(default_factory=dict)
    per_type_bytes: dict[str, int] = field(default_factory=dict)
    lost: int = 0
    reordered: int = 0
    duplicate_sysid: bool = False
    heartbeat_conflicts: int = 0
    signature_failures: int = 0
    bad_values: dict[str, int] = field(default_factory=dict)
    time_reorders: int = 0
    duplicates_dropped: int = 0
    reboots: int = 0
    first_wall_s: float = float("nan")
    last_wall_s: float = float("nan")
    last_vehicle_t_us: int = 0
    _last_seq: dict[int, int] = field(default_factory=dict)
    _heartbeat: dict[int, tuple[int, int]] = field(default_factory=dict)

    def on_message(self, compid: int, seq: int, name: str, nbytes: int, wall_s: float) -> None:
        self.messages += 1
        self.bytes += nbytes
        self.per_type[name] = self.per_type.get(name, 0) + 1
        self.per_type_bytes[name] = self.per_type_bytes.get(name, 0) + nbytes
        if self.first_wall_s != self.first_wall_s:
            self.first_wall_s = wall_s
        self.last_wall_s = wall_s
        last = self._last_seq.get(compid)
        if last is not None:
            gap = (seq - last) % 256
            if gap == 0 or gap > 128:
                self.reordered += 1
                if self.messages > 50 and self.reordered > 0.2 * self.messages:
                    self.duplicate_sysid = True
                return  # keep the highest sequence seen
            self.lost += gap - 1
        self._last_seq[compid] = seq

    def on_heartbeat(self, compid: int, mav_type: int, autopilot: int) -> None:
        prev = self._heartbeat.get(compid)
        if prev is not None and prev != (mav_type, autopilot):
            self.heartbeat_conflicts += 1
            self.duplicate_sysid = True
        self._heartbeat[compid] = (mav_type, autopilot)

    def bad_value(self, name: str) -> None:
        self.bad_values[name] = self.bad_values.get(name, 0) + 1

    @property
    def loss_pct(self) -> float:
        total = self.messages + self.lost
        return 100.0 * self.lost / total if total else 0.0

    def as_dict(self) -> dict[str, Any]:
        span = self.last_wall_s - self.first_wall_s
        rates = ({k: v / span for k, v in self.per_type.items()} if span > 0 else {})
        return {
            "sysid": self.sysid, "messages": self.messages, "bytes": self.bytes,
            "per_type": dict(self.per_type), "per_type_bytes": dict(self.per_type_bytes),
            "rates_hz": rates, "lost": self.lost, "loss_pct": self.loss_pct,
            "reordered": self.reordered, "duplicate_sysid": self.duplicate_sysid,
            "signature_failures": self.signature_failures, "bad_values": dict(self.bad_values),
            "time_reorders": self.time_reorders, "duplicates_dropped": self.duplicates_dropped,
            "reboots": self.reboots, "boot_count": self.reboots,
        }


@dataclass
class LinkCounters:
    """Link-wide counters that belong to no vehicle (garbage cannot name its sender)."""

    bytes_in: int = 0
    chunks: int = 0
    parse_errors: int = 0  # CRC failures and undecodable bytes (pymavlink BAD_DATA)
    bad_signature: int = 0
    unknown_messages: int = 0
    dropped_chunks: int = 0  # input queue overflow (bounded memory)
    dropped_bytes: int = 0
    resync_bytes: int = 0  # tlog bytes skipped to find the next record

    def as_dict(self) -> dict[str, int]:
        return dict(self.__dict__)
