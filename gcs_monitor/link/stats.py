"""Link statistics: per vehicle (sysid) counts, bytes, rates, losses from sequence gaps, errors.

Everything the link layer cannot pass on is counted here, never raised (docs/style.md sec. 7).
Memory is bounded: per-type tables are capped at ``MAX_TYPES`` names, sequence state is kept per
component id (at most 256), and nothing grows with the number of messages.

**Bursts longer than the sequence space.** The 8-bit MAVLink sequence number wraps every 256
packets, so a burst of 300 lost packets reads as 43 and one of 200 as a late packet. Where the
stream carries the sender's clock (``time_boot_ms``, ATTITUDE and GLOBAL_POSITION_INT among
others), the count is bounded by time: between two clock samples of a (sysid, compid) stream the
sender sent about ``rate x elapsed`` packets (``rate`` measured on that stream, in packets per
millisecond of the sender's clock, over windows of ``RATE_WINDOW_MS``). The number lost is known
modulo 256 exactly from the sequence numbers, so the count chosen is the one of that residue
nearest to the time estimate: exact as long as the estimate is within 128 packets of the truth
(at 1000 packets/s: a rate error below 128 / the burst length in ms). Only intervals that
contain a sequence gap are corrected, so a sender that pauses is never counted as loss; a loss
of exactly a multiple of 256 packets with no other gap stays invisible; such an interval (the
clock ahead of the packets by half the sequence space or more, no gap) is also left out of the
rate, which would otherwise read low and misjudge the next bursts. Streams without a clock
keep the modular count.
"""

from __future__ import annotations

import builtins
from dataclasses import dataclass, field
from typing import Any

SEQ_MOD = 256  # MAVLink sequence numbers wrap at 256
SEQ_HALF = SEQ_MOD // 2  # a backward step of less than half the space is a late packet
MAX_TYPES = 400  # per-type tables stop growing here (unknown ids go to "OTHER")
# Duplicate-sysid heuristic: two independent senders with one sysid interleave two sequence
# streams, so roughly half of all steps go backwards, for as long as both send. Reordering by a
# radio or UDP gives a few percent; a reboot seen through a buffering radio gives a short burst
# (the real dronekit tlog peaks at 0.6 for a few dozen packets). So: EWMA of "step went
# backwards" with weight 1/DUP_EWMA_N, and the flag needs it above DUP_THRESHOLD for
# DUP_SUSTAIN consecutive packets of that component.
DUP_EWMA_N = 64
DUP_THRESHOLD = 0.25
DUP_SUSTAIN = 256
# The flag describes the present: it clears when the evidence stops -- the EWMA below
# DUP_THRESHOLD for DUP_SUSTAIN packets of that component, DUP_HEARTBEATS_CLEAR heartbeats of
# the component that agree, DUP_SUSTAIN packets of the vehicle without a clock conflict.
DUP_HEARTBEATS_CLEAR = 5
RATE_WINDOW_S = 5.0  # recent per-type rates are measured over windows of this wall time
RATE_WINDOW_MS = 1000  # a stream's packet rate is measured over this much of the sender's clock
CLOCK_REBOOT_MS = 10_000  # the sender's clock stepping back by more than this: a reboot
MAV_TYPE_GCS = 6
NON_VEHICLE_TYPES = frozenset({MAV_TYPE_GCS, 18, 26, 27, 30})  # GCS, ONBOARD_CONTROLLER, ...


class _SeqState:
    """Sequence tracking of one (sysid, compid) stream, and its clock-bounded loss interval
    (module docstring): since the last clock sample ``clk`` (at sequence number ``s0``),
    ``n_int`` packets were received, ``lost_int`` counted lost and ``n_back`` read as late."""

    __slots__ = ("last", "last_buf", "back_ewma", "high_run", "low_run", "clk", "s0", "n_int",
                 "lost_int", "n_back", "gap_int", "rate", "win_clk", "win_sent")

    def __init__(self, seq: int, buf: bytes) -> None:
        self.last = seq
        self.last_buf = buf
        self.back_ewma = 0.0
        self.high_run = 0
        self.low_run = 0
        self.clk = -1  # sender clock (ms) of the last clock sample; -1: none yet
        self.s0 = seq
        self.n_int = 0
        self.lost_int = 0
        self.n_back = 0
        self.gap_int = False
        self.rate = 0.0  # packets per ms of the sender's clock; 0: not measured yet
        self.win_clk = -1
        self.win_sent = 0


@dataclass
class LinkStats:
    """Statistics of one vehicle (sysid) on one link.

    Sequence gaps are tracked per (sysid, compid) with wraparound at 256: a forward step of
    g > 1 counts g - 1 lost packets; a repeat of the previous packet is a duplicate (dropped by
    the decoder); a backward step of less than 128 is a late (reordered) packet, which was
    counted lost when its successor arrived, so it is taken back off ``lost``. Two senders with
    the same sysid (interleaved sequence streams, a HEARTBEAT whose type/autopilot changes on
    one (sysid, compid), or two interleaving vehicle clocks seen by the assembler) set
    ``duplicate_sysid``; it clears when that evidence stops (the second sender went away), and
    ``duplicate_sysid_seen`` remembers that it happened.

    Attributes
    ----------
    messages, bytes : decoded packets and their wire bytes
    per_type, per_type_bytes : the same per message name
    recent_rates_hz : per-type rates over the last complete ``RATE_WINDOW_S`` of wall time
    lost : packets missing from the sequence (``loss_pct`` relates them to the expected total)
    duplicates : exact repeats of the previous packet (dropped)
    reordered : packets that arrived after a later one
    bad_values : per ``MESSAGE.field``, values that were NaN/inf or physically impossible
    time_backwards : vehicle-time steps backwards that were not reboots (samples dropped)
    time_rejected : time stamps no vehicle clock can carry (beyond 2100, negative, or a lone
        jump ahead of the time line): the samples were dropped (also in ``bad_values`` under
        ``MESSAGE.time_usec`` / ``MESSAGE.time_boot_ms``)
    time_jumps : forward steps of the vehicle clock that the following samples confirmed (an
        outage or a clock step): the time line moved on, nothing was dropped
    reboots : vehicle time restarted (autopilot reboot): the assembler was reset
    imu_held : IMU samples that repeat their instance's previous six values exactly (a held
        value, not a measurement; the assembler keeps the earlier sample and its time)
    unknown_messages : well-framed packets whose id is not in the dialect
    signature_failures : MAVLink 2 packets that failed signing checks (where the sender is known):
        ``unsigned_rejected`` (no signature while signing is required), ``wrong_key`` (the
        signature does not verify: another key, or forged), ``replayed`` (a valid signature
        with a timestamp not newer than the stream's last: a replay)
    signed_packets : packets whose signature verified; ``unsigned_accepted`` unsigned packets
        let through because signing was not required
    lost_wrapped : packets of bursts longer than the sequence space, found by the clock bound
        (included in ``lost``; module docstring)
    mav1_no_instance : per message type, packets in MAVLink 1 framing whose instance id is a
        MAVLink 2 extension (HIGHRES_IMU ``id``): every instance reads as 0;
        ``mav1_instance_repeats`` counts those whose time stamp repeated or stepped back on
        the stream, the sign that several instances were merged into one
    """

    sysid: int
    messages: int = 0
    bytes: int = 0
    per_type: dict[str, int] = field(default_factory=dict)
    per_type_bytes: dict[str, int] = field(default_factory=dict)
    lost: int = 0
    duplicates: int = 0
    reordered: int = 0
    duplicate_sysid_seen: bool = False
    heartbeat_conflicts: int = 0
    signature_failures: int = 0
    unsigned_rejected: int = 0
    wrong_key: int = 0
    replayed: int = 0
    signed_packets: int = 0
    unsigned_accepted: int = 0
    lost_wrapped: int = 0
    mav1_no_instance: dict[str, int] = field(default_factory=dict)
    mav1_instance_repeats: int = 0
    unknown_messages: int = 0
    bad_values: dict[str, int] = field(default_factory=dict)
    time_backwards: int = 0
    time_rejected: int = 0
    time_jumps: int = 0
    clock_conflicts: int = 0  # two vehicle clocks interleaving (assembler)
    duplicates_dropped: int = 0  # same-timestamp samples dropped by the assembler
    # IMU samples whose six values repeat the instance's previous sample bit for bit: the sender
    # held its last value (no real IMU repeats its noise); not taken as new measurements
    imu_held: int = 0
    reboots: int = 0
    primary_imu_switches: int = 0
    first_wall_s: float = float("nan")
    last_wall_s: float = float("nan")
    last_vehicle_t_us: int = 0
    mav_type: int = -1
    autopilot: int = -1
    recent_rates_hz: dict[str, float] = field(default_factory=dict)
    _win_start_s: float = float("nan")
    _win_counts: dict[str, int] = field(default_factory=dict, repr=False)
    _seq: dict[int, _SeqState] = field(default_factory=dict, repr=False)
    _heartbeat: dict[int, tuple[int, int]] = field(default_factory=dict, repr=False)
    _dup_seq: set[int] = field(default_factory=set, repr=False)  # compids interleaving now
    _dup_hb: dict[int, int] = field(default_factory=dict, repr=False)  # compid: agreeing left
    _dup_clock_left: int = field(default=0, repr=False)  # packets until clock evidence expires
    _mav1_last_t: dict[str, int] = field(default_factory=dict, repr=False)

    @property
    def duplicate_sysid(self) -> bool:
        """Two senders share this system id now (see the class docstring)."""
        return bool(self._dup_seq or self._dup_hb or self._dup_clock_left)

    @duplicate_sysid.setter
    def duplicate_sysid(self, evidence: bool) -> None:
        """``True``: evidence from outside the sequence and heartbeat checks (two vehicle clocks
        interleaving, seen by the assembler); it lasts ``DUP_SUSTAIN`` packets."""
        if evidence:
            self._dup_clock_left = DUP_SUSTAIN
            self.duplicate_sysid_seen = True
        else:
            self._dup_seq.clear()
            self._dup_hb.clear()
            self._dup_clock_left = 0

    def on_packet(self, compid: int, seq: int, name: str, buf: builtins.bytes,
                  wall_s: float, clock_ms: int | None = None) -> bool:
        """Account one decoded packet; False if it is an exact repeat of the previous one.

        ``clock_ms``: the sender's clock in the packet (``time_boot_ms``), when it has one; it
        bounds the loss of bursts longer than the sequence space (module docstring).
        """
        st = self._seq.get(compid)
        if st is None:
            st = self._seq[compid] = _SeqState(seq, buf)
        elif seq - st.last == 1 and st.back_ewma == 0.0:
            # fast path, the usual case: next in sequence, no backward step in memory (the EWMA
            # update below would leave back_ewma == 0.0 and high_run == 0 unchanged)
            st.last = seq
            st.last_buf = buf
            st.n_int += 1
        else:
            gap = (seq - st.last) % SEQ_MOD
            back = 0.0
            st.gap_int = True
            if gap == 0:
                if buf == st.last_buf:
                    self.duplicates += 1
                    return False
                back = 1.0  # same seq, different packet: another sender
            elif gap > SEQ_HALF:
                back = 1.0
                self.reordered += 1
                st.n_back += 1
                if self.lost > 0:
                    self.lost -= 1  # it was counted lost when its successor arrived
                    st.lost_int -= 1
            else:
                self.lost += gap - 1
                st.lost_int += gap - 1
                st.last = seq
            st.n_int += 1
            st.last_buf = buf
            st.back_ewma += (back - st.back_ewma) / DUP_EWMA_N
            if st.back_ewma > DUP_THRESHOLD:
                st.high_run += 1
                st.low_run = 0
                if st.high_run >= DUP_SUSTAIN:
                    self._dup_seq.add(compid)
                    self.duplicate_sysid_seen = True
            else:
                st.high_run = 0
                if compid in self._dup_seq:
                    st.low_run += 1
                    if st.low_run >= DUP_SUSTAIN:  # the other sender has stopped
                        self._dup_seq.discard(compid)
        if clock_ms is not None:
            self._clock_sample(st, seq, clock_ms)
        if self._dup_clock_left:
            self._dup_clock_left -= 1
        nbytes = len(buf)
        self.messages += 1
        self.bytes += nbytes
        pt = self.per_type
        count = pt.get(name)
        if count is None:
            if len(pt) >= MAX_TYPES:
                name = "OTHER"
            count = pt.get(name, 0)
        pt[name] = count + 1
        ptb = self.per_type_bytes
        ptb[name] = ptb.get(name, 0) + nbytes
        if self.first_wall_s != self.first_wall_s:
            self.first_wall_s = self._win_start_s = wall_s
        self.last_wall_s = wall_s
        if wall_s - self._win_start_s >= RATE_WINDOW_S:
            self._close_rate_window(wall_s)
        return True

    def _clock_sample(self, st: _SeqState, seq: int, clk: int) -> None:
        """Close the stream's loss interval at a sample of the sender's clock (module
        docstring): correct a modular count that a burst wrapped, measure the rate."""
        if st.clk < 0 or clk < st.clk - CLOCK_REBOOT_MS:  # first clock sample, or a reboot
            st.clk = st.win_clk = clk
            st.win_sent = 0
        elif clk > st.clk:
            dc = clk - st.clk
            if st.gap_int and st.rate > 0.0:
                # lost in the interval: known mod 256 from the sequence numbers, about
                # rate * dc - received from the clock; take the residue nearest the estimate
                received = st.n_int
                # residue in [-128, 128): -1 is a late packet of the previous interval
                residue = (seq - st.s0 - received + SEQ_HALF) % SEQ_MOD - SEQ_HALF
                estimate = st.rate * dc - received
                wraps = max(0, round((estimate - residue) / SEQ_MOD))
                lost = residue + SEQ_MOD * wraps
                if abs(lost - st.lost_int) >= SEQ_HALF:
                    self.lost = max(self.lost + lost - st.lost_int, 0)
                    self.lost_wrapped += max(lost - st.lost_int, 0)
                    if st.n_back:  # the "late" packets were the far side of the burst
                        self.reordered -= st.n_back
                        st.last = seq
                    st.lost_int = lost
            if not st.gap_int and st.rate > 0.0 and st.rate * dc - st.n_int >= SEQ_HALF:
                # the clock says half the sequence space or more went unsent or unseen and the
                # sequence numbers show no gap: a pause of the sender or a lost run of a
                # multiple of 256 (the blind spot above). Either way not a sample of the rate:
                # counted as sending, it would lower the rate that bounds the next bursts
                st.win_clk += dc
            else:
                st.win_sent += st.n_int + st.lost_int
            st.clk = clk
            if clk - st.win_clk >= RATE_WINDOW_MS:
                st.rate = st.win_sent / (clk - st.win_clk)
                st.win_clk = clk
                st.win_sent = 0
        else:
            return  # a clock stamp behind the newest one (older sample): not a boundary
        st.s0 = seq
        st.n_int = 0
        st.lost_int = 0
        st.n_back = 0
        st.gap_int = False

    def on_mav1_instance(self, name: str, t: int) -> None:
        """A message whose instance id is a MAVLink 2 extension arrived in MAVLink 1 framing
        (every instance reads as 0); ``t`` is its time stamp: a repeat or a step back means
        several instances are interleaved in what reads as one."""
        nm = self.mav1_no_instance
        nm[name] = nm.get(name, 0) + 1
        last = self._mav1_last_t.get(name)
        if last is not None and t <= last and last - t < 10_000_000:
            self.mav1_instance_repeats += 1
        self._mav1_last_t[name] = max(t, last) if last is not None and last - t < 10_000_000 \
            else t

    def _close_rate_window(self, wall_s: float) -> None:
        dt = wall_s - self._win_start_s
        old = self._win_counts
        self.recent_rates_hz = {k: (v - old.get(k, 0)) / dt for k, v in self.per_type.items()
                                if v != old.get(k, 0)}
        self._win_counts = dict(self.per_type)
        self._win_start_s = wall_s

    def on_heartbeat(self, compid: int, mav_type: int, autopilot: int) -> None:
        prev = self._heartbeat.get(compid)
        if prev is not None and prev != (mav_type, autopilot):
            self.heartbeat_conflicts += 1
            self._dup_hb[compid] = DUP_HEARTBEATS_CLEAR
            self.duplicate_sysid_seen = True
        elif compid in self._dup_hb:
            left = self._dup_hb[compid] - 1
            if left > 0:
                self._dup_hb[compid] = left
            else:
                del self._dup_hb[compid]
        self._heartbeat[compid] = (mav_type, autopilot)
        if compid == 1 or self.mav_type < 0:
            self.mav_type, self.autopilot = mav_type, autopilot

    def bad_value(self, name: str, n: int = 1) -> None:
        """Count ``n`` bad values of field ``name`` (``MESSAGE.field``)."""
        bv = self.bad_values
        if name not in bv and len(bv) >= MAX_TYPES:
            name = "OTHER"
        bv[name] = bv.get(name, 0) + n

    @property
    def is_vehicle(self) -> bool:
        """A HEARTBEAT says this sysid is a vehicle (not a GCS, companion or radio)."""
        return self.mav_type >= 0 and self.mav_type not in NON_VEHICLE_TYPES

    @property
    def loss_pct(self) -> float:
        total = self.messages + self.lost
        return 100.0 * self.lost / total if total else 0.0

    @property
    def span_s(self) -> float:
        span = self.last_wall_s - self.first_wall_s
        return span if span > 0 else 0.0

    def rates_hz(self) -> dict[str, float]:
        """Mean rate of each message type over the observed wall-time span."""
        span = self.span_s
        if span <= 0:
            return {}
        return {k: v / span for k, v in self.per_type.items()}

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready summary (health queryable)."""
        span = self.span_s
        return {
            "sysid": self.sysid, "is_vehicle": self.is_vehicle, "mav_type": self.mav_type,
            "autopilot": self.autopilot, "messages": self.messages, "bytes": self.bytes,
            "span_s": span, "rate_hz": self.messages / span if span > 0 else 0.0,
            "bytes_per_s": self.bytes / span if span > 0 else 0.0,
            "per_type": dict(self.per_type), "per_type_bytes": dict(self.per_type_bytes),
            "rates_hz": self.rates_hz(), "recent_rates_hz": dict(self.recent_rates_hz),
            "lost": self.lost, "loss_pct": self.loss_pct,
            "duplicates": self.duplicates, "reordered": self.reordered,
            "duplicate_sysid": self.duplicate_sysid,
            "duplicate_sysid_seen": self.duplicate_sysid_seen,
            "heartbeat_conflicts": self.heartbeat_conflicts,
            "signature_failures": self.signature_failures,
            "unsigned_rejected": self.unsigned_rejected, "wrong_key": self.wrong_key,
            "replayed": self.replayed, "signed_packets": self.signed_packets,
            "unsigned_accepted": self.unsigned_accepted, "lost_wrapped": self.lost_wrapped,
            "mav1_no_instance": dict(self.mav1_no_instance),
            "mav1_instance_repeats": self.mav1_instance_repeats,
            "unknown_messages": self.unknown_messages, "bad_values": dict(self.bad_values),
            "bad_values_total": sum(self.bad_values.values()),
            "time_backwards": self.time_backwards, "clock_conflicts": self.clock_conflicts,
            "time_rejected": self.time_rejected, "time_jumps": self.time_jumps,
            "duplicates_dropped": self.duplicates_dropped, "imu_held": self.imu_held,
            "reboots": self.reboots, "boot_count": self.reboots,
            "primary_imu_switches": self.primary_imu_switches,
            "last_vehicle_t_us": self.last_vehicle_t_us,
        }


@dataclass
class LinkCounters:
    """Link-wide counters that belong to no vehicle (garbage cannot name its sender)."""

    bytes_in: int = 0
    chunks: int = 0
    parse_errors: int = 0  # CRC failures and undecodable bytes (pymavlink BAD_DATA)
    garbage_bytes: int = 0  # bytes between packets that are no MAVLink frame
    bad_signature: int = 0  # every packet rejected by signing (the three below together)
    unsigned_rejected: int = 0  # no signature while signing is required
    wrong_key: int = 0  # a signature that does not verify with our key (forged, other key)
    replayed: int = 0  # a valid signature whose timestamp is not newer: a replay
    unknown_messages: int = 0  # valid framing, message id not in the dialect
    duplicates: int = 0  # exact repeats dropped by the decoder
    dropped_chunks: int = 0  # input queue overflow (bounded memory), copied from the source
    dropped_bytes: int = 0
    resync_bytes: int = 0  # tlog bytes skipped to find the next record
    kernel_drops: int = 0  # datagrams the OS dropped because the socket buffer was full

    def as_dict(self) -> dict[str, int]:
        return {k: int(v) for k, v in self.__dict__.items()}
