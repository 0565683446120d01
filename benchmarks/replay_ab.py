"""A/B replay cost of two code trees: CPU time of the same replay, the trees alternated.

Single benchmark runs on a shared machine move by a third (decoding alone, unchanged code:
111x and 149x real time within ten minutes), so a speed change of 10-20 % is measured in pairs:
each round replays the same part of the benchmark flight with tree A, then with tree B, each in a
fresh process (``PYTHONPATH`` of that tree), and the table gives both medians and the median of
the per-round ratios B / A. The flight is ``bench_replay.py``'s (simulated once into
``--cache``); the configurations are built as there.

    git worktree add ../before <commit>
    .venv/bin/python benchmarks/replay_ab.py ../before . --rounds 5

``--worker`` is the child process: one configuration's replay, its CPU time printed.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

CONFIGS = ("default", "fdi")


def _config(name: str) -> object:
    from gcs_monitor.config import MonitorConfig

    base = MonitorConfig()
    if name == "default":
        return base
    # FDI only, as bench_replay.py: every redundant set voted, no estimator of any family
    return (base.with_family("imu", enabled=False).with_family("airdata", estimator="none")
            .with_family("yaw_rate", enabled=False).with_family("actuators", enabled=False))


def worker(tlog: Path, name: str, seconds: float) -> None:
    """Replay the first ``seconds`` of ``tlog`` with this process's code; print CPU seconds."""
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    from gcs_monitor.link.transports import TlogSource
    from gcs_monitor.monitor import Monitor

    chunks = list(TlogSource(tlog))
    t_first = chunks[0][1]
    chunks = [c for c in chunks if c[1] - t_first <= seconds]
    cfg = _config(name)

    def run(part: list[tuple[bytes, float]]) -> None:
        mon = Monitor(cfg)  # type: ignore[arg-type]
        for data, t in part:
            mon.feed(data, t)
        mon.finish()

    run(chunks[: max(1, len(chunks) // 10)])  # imports, numba kernels from the disk cache
    c = time.process_time()
    run(chunks)
    print(f"{time.process_time() - c:.6f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("tree_a", type=Path, nargs="?", help="the code before (a worktree)")
    ap.add_argument("tree_b", type=Path, nargs="?", help="the code after")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--seconds", type=float, default=200.0,
                    help="replay the first S seconds of the flight (tlog time)")
    ap.add_argument("--config", action="append", choices=CONFIGS)
    ap.add_argument("--cache", type=Path,
                    default=Path(tempfile.gettempdir()) / "gcs_bench_replay")
    ap.add_argument("--worker", nargs=2, metavar=("TLOG", "CONFIG"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        worker(Path(args.worker[0]), args.worker[1], args.seconds)
        return
    if args.tree_a is None or args.tree_b is None:
        ap.error("give two code trees (e.g. a worktree of the old commit and .)")
    for tree in (args.tree_a, args.tree_b):
        if not (tree / "gcs_monitor" / "__init__.py").exists():
            ap.error(f"{tree}: not a checkout of this project (no gcs_monitor/__init__.py)")
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from bench_replay import flight_tlog  # the same flight as bench_replay.py

    args.cache.mkdir(parents=True, exist_ok=True)
    tlog = flight_tlog(args.cache, 600.0)
    configs = args.config or list(CONFIGS)
    me = str(Path(__file__).resolve())
    times: dict[tuple[str, str], list[float]] = {}

    def once(tree: Path, name: str) -> float:
        env = {**os.environ, "PYTHONPATH": str(tree.resolve()), "OPENBLAS_NUM_THREADS": "1"}
        out = subprocess.run([sys.executable, me, "--worker", str(tlog), name, "--seconds",
                              str(args.seconds)], env=env, check=True, capture_output=True,
                             text=True).stdout
        return float(out.strip().splitlines()[-1])

    print(f"{tlog.name}, first {args.seconds:.0f} s; A = {args.tree_a}, B = {args.tree_b}; "
          f"load average before: {os.getloadavg()[0]:.1f}", flush=True)
    for r in range(args.rounds):
        for name in configs:
            for label, tree in (("A", args.tree_a), ("B", args.tree_b)):
                times.setdefault((name, label), []).append(once(tree, name))
        print(f"round {r + 1}/{args.rounds}: " + ", ".join(
            f"{n} A {times[(n, 'A')][-1]:.2f} s B {times[(n, 'B')][-1]:.2f} s" for n in configs),
            flush=True)
    print("\n| configuration | A: CPU s (median) | B: CPU s (median) | B / A (median of rounds) "
          "| rounds |\n|---|---|---|---|---|")
    for n in configs:
        a, b = times[(n, "A")], times[(n, "B")]
        ratio = statistics.median(y / x for x, y in zip(a, b, strict=True))
        print(f"| {n} | {statistics.median(a):.2f} | {statistics.median(b):.2f} | {ratio:.3f} "
              f"| {len(a)} |")
    print(f"\nload average after: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
