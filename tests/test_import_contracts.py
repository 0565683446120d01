"""The layer rules (pyproject [tool.importlinter]) hold, a forbidden import breaks them, and no
import cycle exists, not even one hidden in a function-local import."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LINT = [sys.executable, "-c", "import sys; from importlinter.cli import lint_imports_command; "
        "sys.exit(lint_imports_command())"]


def _lint(cwd: Path) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": str(cwd)}
    return subprocess.run([*LINT, "--no-cache"], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=300, check=False)


def test_the_contracts_hold() -> None:
    res = _lint(ROOT)
    assert res.returncode == 0, res.stdout + res.stderr
    assert "0 broken" in res.stdout


def test_a_forbidden_import_breaks_them(tmp_path: Path) -> None:
    for pkg in ("gcs_monitor", "sim_vehicle", "dashboards"):
        shutil.copytree(ROOT / pkg, tmp_path / pkg,
                        ignore=shutil.ignore_patterns("__pycache__", "*.nbi", "*.nbc"))
    shutil.copy(ROOT / "pyproject.toml", tmp_path / "pyproject.toml")
    voting = tmp_path / "gcs_monitor" / "fdi" / "voting.py"
    voting.write_text(voting.read_text() + "\nfrom sim_vehicle import scenario  # noqa\n")
    res = _lint(tmp_path)
    assert res.returncode != 0
    assert "nothing on the monitoring path imports the simulator BROKEN" in res.stdout
    assert "gcs_monitor.fdi.voting -> sim_vehicle.scenario" in res.stdout


def import_cycles(cwd: Path, *packages: str) -> list[list[str]]:
    """Strongly connected components (more than one module) of the import graph of
    ``packages`` under ``cwd``, function-local imports included (grimp reads every import
    statement, so a cycle hidden inside a function counts)."""
    code = (
        "import json, sys, grimp\n"
        "g = grimp.build_graph(*sys.argv[1:])\n"
        "mods = g.modules\n"
        "edges = {m: sorted(w for w in g.find_modules_directly_imported_by(m) if w in mods)"
        " for m in mods}\n"
        "print(json.dumps(edges))\n")
    env = {**os.environ, "PYTHONPATH": str(cwd)}
    res = subprocess.run([sys.executable, "-c", code, *packages], cwd=cwd, env=env,
                         capture_output=True, text=True, timeout=300, check=True)
    edges: dict[str, list[str]] = json.loads(res.stdout)
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []
    for root in sorted(edges):  # iterative Tarjan
        if root in index:
            continue
        work = [(root, iter(edges[root]))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = len(index)
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(edges[w])))
                elif w in on_stack:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    x = stack.pop()
                    on_stack.discard(x)
                    comp.append(x)
                    if x == v:
                        break
                if len(comp) > 1:
                    out.append(sorted(comp))
    return out


def test_no_import_cycles_not_even_inside_functions() -> None:
    assert import_cycles(ROOT, "gcs_monitor", "sim_vehicle", "dashboards") == []


def test_a_cycle_hidden_in_a_function_is_found(tmp_path: Path) -> None:
    pkg = tmp_path / "cyc"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from cyc import b\n")
    (pkg / "b.py").write_text("def f():\n    from cyc import a\n    return a\n")
    (pkg / "c.py").write_text("from cyc import a\n")
    assert import_cycles(tmp_path, "cyc") == [["cyc.a", "cyc.b"]]
