"""The evaluation package's imports: no cycle, and no import hidden inside a function."""

from __future__ import annotations

import ast
from pathlib import Path

import gcs_monitor.evaluation

ROOT = Path(gcs_monitor.evaluation.__file__).parent
PKG = "gcs_monitor.evaluation"
# function-local imports allowed: heavy optional plotting only (report.pyplot)
LOCAL_OK = {("report", "matplotlib"), ("report", "matplotlib.pyplot")}


def _modules() -> dict[str, ast.Module]:
    out = {}
    for p in sorted(ROOT.rglob("*.py")):
        name = ".".join(p.relative_to(ROOT).with_suffix("").parts).removesuffix("__init__")
        out[name.rstrip(".")] = ast.parse(p.read_text(), str(p))
    return out


def _targets(node: ast.Import | ast.ImportFrom) -> list[str]:
    if isinstance(node, ast.Import):
        return [a.name for a in node.names]
    mod = node.module or ""
    if mod in (PKG, f"{PKG}.papers"):  # from gcs_monitor.evaluation import campaign, ...
        return [f"{mod}.{a.name}" for a in node.names]
    return [mod]


def test_no_import_cycle_inside_the_package() -> None:
    graph: dict[str, set[str]] = {}
    for name, tree in _modules().items():
        deps = {t.removeprefix(PKG + ".") for n in ast.walk(tree)
                if isinstance(n, ast.Import | ast.ImportFrom) for t in _targets(n)
                if t.startswith(PKG + ".")}
        graph[name] = deps
    done: set[str] = set()

    def visit(n: str, path: tuple[str, ...]) -> None:
        assert n not in path, f"import cycle: {' -> '.join(path + (n,))}"
        if n in done:
            return
        for d in graph.get(n, ()):
            visit(d, path + (n,))
        done.add(n)

    for n in graph:
        visit(n, ())


def test_no_function_local_imports() -> None:
    found = []
    for name, tree in _modules().items():
        for fn in ast.walk(tree):
            if isinstance(fn, ast.FunctionDef | ast.AsyncFunctionDef):
                for n in ast.walk(fn):
                    if isinstance(n, ast.Import | ast.ImportFrom):
                        found += [(name, t) for t in _targets(n) if (name, t) not in LOCAL_OK]
    assert not found, found
