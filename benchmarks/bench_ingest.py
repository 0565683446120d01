"""Ingest cost per MAVLink message: decode, and decode + FrameAssembler, CPU time.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python -m benchmarks.bench_ingest [--duration-s 30]
(from the repository root: the input comes from ``tests/helpers/mavgen.py``).

Input: the telemetry contract's full message mix for one vehicle with three IMUs
(``MavGen``: ~630 msg/s), cut into 16 KiB chunks as a .tlog or UDP reader
delivers them. Each row is the best of ``--repeat`` passes in ``time.process_time``. Budget
(issue 3): a 10-minute, ~430 msg/s flight replays at >= 100x real time, so ingest must stay
well under 20 µs per message. ``benchmarks/bench_replay.py`` measures the same stages on a
simulated flight, in x real time.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

from gcs_monitor.link.decode import Decoder
from gcs_monitor.telemetry.assembler import FrameAssembler
from tests.helpers.mavgen import MavGen, join

BUDGET_US = 20.0
CHUNK_BYTES = 16384


def _best_of(n: int, fn: Callable[[], None]) -> float:
    best = float("inf")
    for _ in range(n):
        t0 = time.process_time()
        fn()
        best = min(best, time.process_time() - t0)
    return best


def bench(duration_s: float, repeat: int) -> tuple[int, list[tuple[str, float]]]:
    """(messages, rows of (stage, best µs per message))."""
    data = join(MavGen().packets(duration_s))
    chunks = [data[i:i + CHUNK_BYTES] for i in range(0, len(data), CHUNK_BYTES)]
    n_msgs = len(Decoder().feed(data, 0.0))

    def decode_only() -> None:
        d = Decoder()
        for c in chunks:
            d.feed(c, 0.0)

    def decode_assemble() -> None:
        d = Decoder()
        a = FrameAssembler(stats=d.vehicle_stats(1), align_delay_us=100_000)
        push = a.push
        for c in chunks:
            for m in d.feed(c, 0.0):
                push(m)

    rows = [("decode (Decoder.feed)", decode_only), ("decode + FrameAssembler", decode_assemble)]
    return n_msgs, [(name, _best_of(repeat, fn) / n_msgs * 1e6) for name, fn in rows]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--duration-s", type=float, default=30.0, help="synthetic telemetry, s")
    ap.add_argument("--repeat", type=int, default=3, help="passes; the best one is reported")
    args = ap.parse_args()
    n_msgs, rows = bench(args.duration_s, args.repeat)
    print(f"{n_msgs} messages ({n_msgs / args.duration_s:.0f} msg/s of vehicle time), "
          f"{CHUNK_BYTES} B chunks, best of {args.repeat}, CPU time")
    print(f"| stage | µs/msg | msg/s | budget < {BUDGET_US:.0f} µs/msg |")
    print("|---|---|---|---|")
    for name, us in rows:
        print(f"| {name} | {us:.1f} | {1e6 / us:.0f} | {'met' if us < BUDGET_US else 'NOT met'} |")


if __name__ == "__main__":
    main()
