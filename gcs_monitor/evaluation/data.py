"""Where the real flight data is: one function, used by the real-data experiments and the tests.

The folder holds the files of ``shared/data/real`` (its README describes them). It is found, in
this order: an explicit path (``gcs-monitor evaluate --data-dir``), the environment variable
``GCS_DATA_DIR``, then ``../shared/data/real`` beside the repository root (the root is found from
this file's location, so nothing depends on where the repository is checked out).
"""

from __future__ import annotations

import os
from pathlib import Path

DATA_DIR_ENV = "GCS_DATA_DIR"
REPO_ROOT = Path(__file__).resolve().parents[2]  # gcs_monitor/evaluation/data.py -> repository
DEFAULT_DATA_DIR = REPO_ROOT.parent / "shared" / "data" / "real"


class RealDataMissing(FileNotFoundError):
    """A real-data file an experiment needs is not where :func:`real_data_dir` points."""


def real_data_dir(explicit: Path | str | None = None) -> Path:
    """The real-data folder: ``explicit``, else ``$GCS_DATA_DIR``, else :data:`DEFAULT_DATA_DIR`.

    The folder is not checked here (``gcs-monitor evaluate --list`` must work without it); use
    :func:`real_data_file` for a file an experiment cannot run without.
    """
    if explicit is not None and str(explicit):
        return Path(explicit).expanduser()
    env = os.environ.get(DATA_DIR_ENV, "")
    return Path(env).expanduser() if env else DEFAULT_DATA_DIR


def missing_message(path: Path, *, cli: bool = True) -> str:
    """What to tell the user when ``path`` is not there: ``gcs-monitor evaluate`` (``cli``) or a
    skipped test."""
    how = f"set {DATA_DIR_ENV} or pass --data-dir" if cli else f"set {DATA_DIR_ENV}"
    return f"real data not found: {how} (looked for {path}; default {DEFAULT_DATA_DIR})"


def real_data_file(data_dir: Path, relative: str) -> Path:
    """``data_dir / relative``, or :class:`RealDataMissing` naming the variable to set."""
    path = data_dir / relative
    if not path.exists():
        raise RealDataMissing(missing_message(path))
    return path
