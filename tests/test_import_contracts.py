"""The layer rules (pyproject [tool.importlinter]) hold, and a forbidden import breaks them."""

from __future__ import annotations

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
