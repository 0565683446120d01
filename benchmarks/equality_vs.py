"""Replay equality against a base commit, in one command (the check ``docs/results.md`` cites).

    python benchmarks/equality_vs.py --base b213565 [--data-dir DIR] [--out DIR] [--jobs 2]

1. A temporary detached ``git worktree`` of ``--base`` is created; it is removed at the end, also
   after a failed step, Ctrl-C or SIGTERM.
2. The fixed flights are flown with the *base* tree, so both sides read the same bytes: the
   preset of ``gcs-monitor demo`` (``demo_airdata_faults`` with its own seed),
   ``lu2016_turbulence``, and the first faulty scenario of the ``triplex`` preset set (6 runs,
   seed 0), each a .tlog of ``sim_vehicle.run.run_scenario(..., live=False)``. When the real data
   is there (``--data-dir``, else ``$GCS_DATA_DIR``, else ``../shared/data/real`` beside the
   repository, as ``gcs_monitor.evaluation.data.real_data_dir``), also the Zipline flight 16951
   converted with Lu2016 IMU faults injected (``gcs-monitor convert --inject lu2016``).
3. Each tree records every tlog in the three configurations of ``benchmarks/replay_equality.py``
   (``default``, ``imu2``, ``fdi``; with the tree's own copy of the script) and writes the alarm
   journal of ``gcs-monitor replay TLOG --journal J --quiet``.
4. The records are compared by this tree's ``replay_equality.py compare A B --atol 0``, the
   journals line by line without their wall-time fields. A Markdown table (flight,
   configuration, identical / differs: first difference) goes to stdout, and with ``--out`` to
   ``DIR/equality_vs.md`` with the log of every step in ``DIR/equality_vs_logs/``.

The new side is this repository's working tree. Every step is a subprocess with the PYTHONPATH of
its tree (``--jobs`` at a time, progress on stderr); this file itself imports only the standard
library, and run with the base tree's PYTHONPATH it flies the simulated flights (``fly``).

Exit status: 0 when everything is identical, 1 when something differs, 2 when a step failed.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import re
import shlex
import signal
import subprocess
import sys
import tempfile
import threading
import time
import traceback
from collections.abc import Iterator, Sequence
from concurrent.futures import FIRST_EXCEPTION, Future, ThreadPoolExecutor, wait
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
EQUALITY_SCRIPT = Path("benchmarks") / "replay_equality.py"

# `gcs-monitor demo`'s default --preset (its TOML holds the seed the demo flies with)
DEMO_PRESET = "demo_airdata_faults"
TURBULENCE_PRESET = "lu2016_turbulence"
TRIPLEX_SET, TRIPLEX_RUNS, TRIPLEX_SEED = "triplex", 6, 0
SIMULATED = ("demo", "lu2016", "triplex")
ZIPLINE_CSV = Path("zipline_launch") / "flight_16951.csv"
DATA_DIR_ENV = "GCS_DATA_DIR"

CONFIGS = ("default", "imu2", "fdi")  # the configurations of replay_equality.py
JOURNAL = "journal"
WALL_TIME_KEYS = ("wall_time_s", "wall_time")  # the journal's only fields read from the clock
SIDES = ("base", "new")
TLOG_PREFIX = "tlog: "  # how `fly` names the file it wrote


# -- pure helpers (tests/benchmarks/test_equality_vs.py) ------------------------------------------
@dataclass(frozen=True)
class Row:
    """One line of the table: ``difference`` is None when the two sides are identical."""

    flight: str
    configuration: str
    difference: str | None


def default_data_dir(explicit: Path | None = None) -> Path:
    """``explicit``, else ``$GCS_DATA_DIR``, else ``../shared/data/real`` beside the repository
    (the rule of ``gcs_monitor.evaluation.data.real_data_dir``, without importing a tree)."""
    if explicit is not None and str(explicit):
        return explicit.expanduser()
    env = os.environ.get(DATA_DIR_ENV, "")
    return Path(env).expanduser() if env else REPO.parent / "shared" / "data" / "real"


def normalise_journal(text: str) -> list[dict[str, Any]]:
    """The alarm records of a journal without the fields stamped from the wall clock."""
    records = []
    for line in text.splitlines():
        if line.strip():
            rec = json.loads(line)
            for key in WALL_TIME_KEYS:
                rec.pop(key, None)
            records.append(rec)
    return records


def _short(value: Any, width: int = 40) -> str:
    s = json.dumps(value) if isinstance(value, (dict, list)) else repr(value)
    return s if len(s) <= width else s[: width - 3] + "..."


def journal_difference(base: str, new: str) -> str | None:
    """The first difference of two journals (wall-time fields aside), None when identical."""
    a, b = normalise_journal(base), normalise_journal(new)
    for i, (x, y) in enumerate(zip(a, b, strict=False), start=1):
        if x == y:
            continue
        keys = [k for k in dict.fromkeys([*x, *y]) if x.get(k) != y.get(k)]
        what = ", ".join(f"{k} {_short(x.get(k))} vs {_short(y.get(k))}" for k in keys[:2])
        more = f" (+{len(keys) - 2} fields)" if len(keys) > 2 else ""
        where = f"{x.get('channel_name', '?')} {x.get('state', '?')}"
        return f"alarm {i} ({where}): {what}{more}"
    if len(a) != len(b):
        return f"{len(a)} vs {len(b)} alarms"
    return None


_MAX_DIFF = re.compile(r"(\w+)=(\S+)")
_COUNT_MISMATCH = re.compile(r"\d+ vs \d+ (estimates|statuses)")


def record_difference(report: str) -> str:
    """The first line of a ``replay_equality.py compare`` report that shows a difference."""
    for raw in report.splitlines():
        line = raw.strip()
        if line.startswith("RESULT:"):
            break
        if ("identical: False" in line or _COUNT_MISMATCH.search(line)
                or line.startswith(("channel ", "decisions identical"))):
            return line
        if "max |diff|" in line:
            name, _, tail = line.partition(":")
            nonzero = [f"{k}={v}" for k, v in _MAX_DIFF.findall(tail.split("max |diff|", 1)[1])
                       if float(v) != 0.0]
            if nonzero:
                return f"{name}: max |diff| {' '.join(nonzero)}"
    return "records differ (see the compare log)"


def _cell(text: str) -> str:
    return " ".join(text.split()).replace("|", "\\|")


def format_table(rows: Sequence[Row]) -> str:
    """The Markdown table: flight, configuration, identical / differs: first difference."""
    lines = ["| flight | configuration | result |", "|---|---|---|"]
    for r in rows:
        result = "identical" if r.difference is None else f"differs: {r.difference}"
        lines.append(f"| {_cell(r.flight)} | {_cell(r.configuration)} | {_cell(result)} |")
    return "\n".join(lines)


# -- flying (runs with the base tree's PYTHONPATH) ------------------------------------------------
def fly(what: str, out: Path) -> Path:
    """Simulate one fixed flight to ``out``; the .tlog's path."""
    from sim_vehicle.run import run_scenario
    from sim_vehicle.scenario import load_scenario

    if what == "triplex":
        from sim_vehicle.campaigns import generate_set

        scenarios = generate_set(TRIPLEX_SET, TRIPLEX_RUNS, seed=TRIPLEX_SEED)
        sc = next(s for s in scenarios if s.faults)
    else:
        sc = load_scenario({"demo": DEMO_PRESET, "lu2016": TURBULENCE_PRESET}[what])
    res = run_scenario(sc, out, live=False, progress=False)
    if res.tlog_path is None:
        raise RuntimeError(f"{what}: run_scenario wrote no .tlog")
    return Path(res.tlog_path)


# -- subprocesses ---------------------------------------------------------------------------------
class StepFailed(RuntimeError):
    """A subprocess ended with an unexpected exit status."""

    def __init__(self, label: str, returncode: int, log: Path, tail: str) -> None:
        super().__init__(f"{label}: exit status {returncode} (log {log})")
        self.tail = tail


class Cancelled(RuntimeError):
    """The run is stopping; no new subprocess starts."""


class Runner:
    """Runs subprocesses at most ``jobs`` at a time, logs each, reports progress on stderr."""

    def __init__(self, jobs: int, total: int, log_dir: Path) -> None:
        self._slots = threading.Semaphore(jobs)
        self._lock = threading.Lock()
        self._procs: set[subprocess.Popen[str]] = set()
        self._stopping = False
        self._done = 0
        self.total = total
        self.log_dir = log_dir

    def run(self, label: str, argv: Sequence[str], *, env: dict[str, str], cwd: Path,
            ok: tuple[int, ...] = (0,)) -> tuple[int, str]:
        """Exit status and output (stdout and stderr) of ``argv``; StepFailed if not in ``ok``."""
        log = self.log_dir / (re.sub(r"[^\w.-]+", "_", label) + ".log")
        with self._slots:
            with self._lock:
                if self._stopping:
                    raise Cancelled(label)
                t0 = time.perf_counter()
                proc = subprocess.Popen(list(argv), env=env, cwd=cwd, text=True,
                                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
                self._procs.add(proc)
            try:
                out, _ = proc.communicate()
            finally:
                with self._lock:
                    self._procs.discard(proc)
        log.write_text(f"$ {shlex.join(argv)}\n{out}")
        with self._lock:
            if self._stopping:
                raise Cancelled(label)
            self._done += 1
            status = "ok" if proc.returncode in ok else f"FAILED (exit {proc.returncode})"
            print(f"[{self._done:2d}/{self.total}] {label}: {status}, "
                  f"{time.perf_counter() - t0:.0f} s", file=sys.stderr, flush=True)
        if proc.returncode not in ok:
            raise StepFailed(label, proc.returncode, log, "\n".join(out.splitlines()[-20:]))
        return proc.returncode, out

    def stop(self) -> None:
        """Start nothing more and terminate the subprocesses that are running."""
        with self._lock:
            self._stopping = True
            procs = list(self._procs)
        for p in procs:
            p.terminate()


def tree_env(tree: Path) -> dict[str, str]:
    env = dict(os.environ)
    env.update(PYTHONPATH=str(tree), OPENBLAS_NUM_THREADS="1", MAVLINK20="1")
    return env


def git(*args: str) -> str:
    return subprocess.run(["git", *args], cwd=REPO, check=True, capture_output=True,
                          text=True).stdout.strip()


@contextmanager
def base_worktree(commit: str, parent: Path) -> Iterator[Path]:
    """A detached worktree of ``commit`` under ``parent``, removed on the way out."""
    path = parent / "base_tree"
    git("worktree", "add", "--quiet", "--detach", str(path), commit)
    try:
        yield path
    finally:
        r = subprocess.run(["git", "worktree", "remove", "--force", str(path)], cwd=REPO,
                           capture_output=True, text=True)
        if r.returncode != 0:
            print(f"warning: could not remove the worktree {path}: {r.stderr.strip()}",
                  file=sys.stderr)


def check_tree(tree: Path, cwd: Path) -> None:
    """Fail unless ``gcs_monitor`` and ``sim_vehicle`` import from ``tree`` with its PYTHONPATH
    (run from ``cwd``, where the steps run)."""
    code = "import gcs_monitor, sim_vehicle; print(gcs_monitor.__file__, sim_vehicle.__file__)"
    out = subprocess.run([sys.executable, "-c", code], env=tree_env(tree), cwd=cwd, check=True,
                         capture_output=True, text=True).stdout.split()
    for f in out:
        if not Path(f).resolve().is_relative_to(tree.resolve()):
            raise RuntimeError(f"with PYTHONPATH={tree} the packages import from {f}")


def equality_script(tree: Path, cwd: Path) -> Path:
    """The tree's own replay_equality.py, else this tree's copy if it imports with ``tree``."""
    own = tree / EQUALITY_SCRIPT
    if own.is_file():
        return own
    ours = REPO / EQUALITY_SCRIPT
    r = subprocess.run([sys.executable, str(ours), "--help"], env=tree_env(tree), cwd=cwd,
                       capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"{tree} has no {EQUALITY_SCRIPT} and ours does not import there:\n"
                           f"{r.stderr.strip()}")
    return ours


# -- the check ------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Check:
    runner: Runner
    pool: ThreadPoolExecutor
    trees: dict[str, Path]
    scripts: dict[str, Path]
    work: Path

    def flight(self, key: str, zipline_csv: Path | None) -> tuple[str, list[Row]]:
        """Fly one flight with the base tree, record it with both, compare; a line naming the
        .tlog (size, SHA-256) and the flight's rows."""
        base = self.trees["base"]
        out = self.work / "flights" / key
        if zipline_csv is None:
            _, text = self.runner.run(
                f"fly {key} (base)", [sys.executable, str(Path(__file__).resolve()), "fly", key,
                                      str(out)], env=tree_env(base), cwd=self.work)
            (tlog,) = (Path(line.removeprefix(TLOG_PREFIX)) for line in text.splitlines()
                       if line.startswith(TLOG_PREFIX))
        else:
            self.runner.run(f"convert {zipline_csv.name} --inject lu2016 (base)",
                            [sys.executable, "-m", "gcs_monitor.cli", "convert", str(zipline_csv),
                             "--inject", "lu2016", "--out", str(out)],
                            env=tree_env(base), cwd=self.work)
            (tlog,) = out.glob("*.tlog")
        name = tlog.stem
        digest = hashlib.sha256(tlog.read_bytes()).hexdigest()
        about = f"`{tlog.name}` ({tlog.stat().st_size} bytes, SHA-256 {digest[:16]})"
        jobs: dict[tuple[str, str], Future[Path]] = {}
        for side in SIDES:
            for cfg in (*CONFIGS, JOURNAL):
                jobs[side, cfg] = self.pool.submit(self._record, side, cfg, tlog, name)
        rows = []
        for cfg in CONFIGS:
            a, b = jobs["base", cfg].result(), jobs["new", cfg].result()
            rc, report = self.runner.run(
                f"compare {name} {cfg}",
                [sys.executable, str(REPO / EQUALITY_SCRIPT), "compare", str(a), str(b),
                 "--atol", "0"], env=tree_env(REPO), cwd=self.work, ok=(0, 1))
            same = rc == 0 and "RESULT: SAME" in report
            rows.append(Row(name, cfg, None if same else record_difference(report)))
        ja, jb = jobs["base", JOURNAL].result(), jobs["new", JOURNAL].result()
        diff = journal_difference(ja.read_text(), jb.read_text())
        rows.append(Row(name, "journal (wall time stripped)", diff))
        return about, rows

    def _record(self, side: str, cfg: str, tlog: Path, name: str) -> Path:
        tree = self.trees[side]
        folder = self.work / side
        if cfg == JOURNAL:
            out = folder / f"{name}.journal.jsonl"
            argv = [sys.executable, "-m", "gcs_monitor.cli", "replay", str(tlog), "--journal",
                    str(out), "--quiet"]
            label = f"replay --journal {name} ({side})"
        else:
            out = folder / f"{name}.{cfg}.pkl"
            argv = [sys.executable, str(self.scripts[side]), "record", str(tlog), cfg, str(out)]
            label = f"record {name} {cfg} ({side})"
        self.runner.run(label, argv, env=tree_env(tree), cwd=self.work)
        if cfg == JOURNAL and not out.exists():
            out.write_text("")  # no alarm and nothing opened: an empty journal
        return out


def _wait_all(futures: Sequence[Future[tuple[str, list[Row]]]],
              runner: Runner) -> tuple[list[str], list[Row]]:
    pending = set(futures)
    while pending:
        done, pending = wait(pending, timeout=0.5, return_when=FIRST_EXCEPTION)
        for f in done:
            exc = f.exception()
            if exc is not None:
                runner.stop()
                raise exc
    results = [f.result() for f in futures]
    return [about for about, _ in results], [row for _, rows in results for row in rows]


def _interrupt(signum: int, frame: Any) -> None:
    raise KeyboardInterrupt


def run_check(args: argparse.Namespace, command: str) -> int:
    t0 = time.perf_counter()
    base_commit = git("rev-parse", "--verify", f"{args.base}^{{commit}}")
    head = git("rev-parse", "HEAD")
    dirty = bool(git("status", "--porcelain", "--untracked-files=no"))
    data_dir = default_data_dir(args.data_dir)
    zipline = data_dir / ZIPLINE_CSV
    if args.data_dir is not None and not zipline.is_file():
        print(f"equality_vs: {zipline} not found (--data-dir)", file=sys.stderr)
        return 2
    flights: list[tuple[str, Path | None]] = [(k, None) for k in SIMULATED]
    notes = []
    if zipline.is_file():
        flights.append(("zipline", zipline))
    else:
        notes.append(f"Zipline flight skipped: {zipline} not found (set {DATA_DIR_ENV} or pass "
                     "--data-dir).")
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
    signal.signal(signal.SIGTERM, _interrupt)
    with tempfile.TemporaryDirectory(prefix="equality_vs_") as tmp:
        work = Path(tmp)
        log_dir = args.out / "equality_vs_logs" if args.out is not None else work / "logs"
        for d in (work / "flights", work / "base", work / "new", log_dir):
            d.mkdir(parents=True, exist_ok=True)
        print(f"equality_vs: base {base_commit[:12]} in a temporary worktree, new = {REPO}; "
              f"{len(flights)} flights, --jobs {args.jobs}", file=sys.stderr)
        with base_worktree(base_commit, work) as base_tree:
            trees = {"base": base_tree, "new": REPO}
            for tree in trees.values():
                check_tree(tree, work)
            scripts = {side: equality_script(tree, work) for side, tree in trees.items()}
            # per flight: fly, 2 x (3 records + 1 journal), 3 compares
            runner = Runner(args.jobs, len(flights) * 12, log_dir)
            with ThreadPoolExecutor(max_workers=16 * len(flights)) as pool:
                check = Check(runner, pool, trees, scripts, work)
                futures = [pool.submit(check.flight, key, csv) for key, csv in flights]
                try:
                    tlogs, rows = _wait_all(futures, runner)
                except StepFailed as exc:
                    print(f"equality_vs: {exc}\n{exc.tail}", file=sys.stderr)
                    return 2
                except BaseException:
                    runner.stop()
                    raise
    wall_s = time.perf_counter() - t0
    script_note = ", ".join(
        f"{side} by {'its own copy' if s.is_relative_to(trees[side]) else 'the new copy'} of "
        f"`{EQUALITY_SCRIPT}`" for side, s in scripts.items())
    n_same = sum(r.difference is None for r in rows)
    report = "\n".join([
        f"Command: `{command}`",
        "",
        f"Base: `{base_commit}` (temporary worktree). New: `{head}`"
        + (" with uncommitted changes" if dirty else "") + ".",
        f"Flights flown with the base tree: {', '.join(tlogs)}.",
        "",
        f"Records made {script_note}; compared with "
        f"`replay_equality.py compare --atol 0`; journals of `gcs-monitor replay --journal` "
        f"compared without {' / '.join(WALL_TIME_KEYS)}.",
        *notes,
        *([f"Logs of every step: `{log_dir}/`."] if args.out is not None else []),
        "",
        format_table(rows),
        "",
        f"{n_same} of {len(rows)} identical; wall time {wall_s / 60:.1f} min "
        f"({wall_s:.0f} s, --jobs {args.jobs}).",
    ])
    print(report)
    if args.out is not None:
        (args.out / "equality_vs.md").write_text(report + "\n")
    return 0 if n_same == len(rows) else 1


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] == ["fly"]:
        ap = argparse.ArgumentParser(prog="equality_vs.py fly",
                                     description="fly one fixed flight (base tree's PYTHONPATH)")
        ap.add_argument("what", choices=SIMULATED)
        ap.add_argument("out", type=Path)
        a = ap.parse_args(argv[1:])
        print(f"{TLOG_PREFIX}{fly(a.what, a.out)}")
        return 0
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", required=True, help="commit to compare with (e.g. b213565)")
    ap.add_argument("--data-dir", type=Path,
                    help=f"real flight data (default ${DATA_DIR_ENV}, else ../shared/data/real)")
    ap.add_argument("--out", type=Path, help="also write the table (equality_vs.md) and the logs")
    ap.add_argument("--jobs", type=int, default=2, help="subprocesses at a time (default 2)")
    args = ap.parse_args(argv)
    if args.jobs < 1:
        ap.error("--jobs must be >= 1")
    command = shlex.join(["python", sys.argv[0], *argv])
    try:
        return run_check(args, command)
    except KeyboardInterrupt:
        print("equality_vs: interrupted; temporary worktree removed", file=sys.stderr)
        return 130
    except Exception:
        traceback.print_exc()
        return 2


if __name__ == "__main__":
    sys.exit(main())
