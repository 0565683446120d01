"""The loader of the compiled kernels (gcs_monitor.core.kernels) and its dependency digests."""

from __future__ import annotations

import ast
import importlib.util
from pathlib import Path

import pytest

from gcs_monitor.core.kernels import StaleKernelError, load_kernels, source_digest

ROOT = Path(__file__).resolve().parents[3]
KERNEL_FILES = sorted(
    p for pkg in ("gcs_monitor", "sim_vehicle") for p in (ROOT / pkg).rglob("_*_jit.py")
)


def _module(path: Path) -> str:
    return ".".join(path.relative_to(ROOT).with_suffix("").parts)


def _is_module(name: str) -> bool:
    try:
        return importlib.util.find_spec(name) is not None
    except ModuleNotFoundError:  # parent is a module, not a package: name is an attribute
        return False


def test_kernel_files_found() -> None:
    names = {p.name for p in KERNEL_FILES}
    assert {"_two_stage_jit.py", "_otsekf_jit.py", "_mhe_jit.py", "_servo_jit.py",
            "_rigid_body_jit.py", "_channels_jit.py"} <= names


@pytest.mark.parametrize("path", KERNEL_FILES, ids=lambda p: p.name)
def test_every_kernel_loads_with_current_dependency_digests(path: Path) -> None:
    """A digest left behind after an edit of _linalg.py or constants.py fails here (and in the
    monitor itself) instead of letting numba's cache run the old compiled code."""
    load_kernels(_module(path))


@pytest.mark.parametrize("path", KERNEL_FILES, ids=lambda p: p.name)
def test_every_project_import_of_a_kernel_is_a_declared_dependency(path: Path) -> None:
    """numba's per-file cache does not see the files a kernel imports from: each run-time import
    of a project module must be listed in KERNEL_DEPENDENCIES (imports under TYPE_CHECKING only
    serve annotations)."""
    tree = ast.parse(path.read_text())
    imported: set[str] = set()
    for node in tree.body:  # module level only; an `if TYPE_CHECKING:` block is an ast.If
        if isinstance(node, ast.ImportFrom) and node.module:
            for a in node.names:  # `from pkg import module` imports pkg.module
                sub = f"{node.module}.{a.name}"
                imported.add(sub if _is_module(sub) else node.module)
        elif isinstance(node, ast.Import):
            imported.update(a.name for a in node.names)
    project = {m for m in imported if m.split(".")[0] in ("gcs_monitor", "sim_vehicle")}
    declared = set(getattr(load_kernels(_module(path)), "KERNEL_DEPENDENCIES", {}))
    assert project <= declared, f"{path.name} imports {sorted(project - declared)} undeclared"


def test_a_stale_digest_refuses_to_load(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    mod = tmp_path / "stale_kernel_for_test_jit.py"
    mod.write_text('KERNEL_DEPENDENCIES = {"gcs_monitor.core.constants": "0000000000000000"}\n')
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(StaleKernelError, match=source_digest("gcs_monitor.core.constants")):
        load_kernels("stale_kernel_for_test_jit")
