"""Test-wide settings and fixtures.

Hypothesis draws its examples from a fixed seed (``derandomize``), so the same commit gives the
same test run, as the project asks of every random draw. ``HYPOTHESIS_PROFILE=explore pytest``
draws new examples on every run, to look for failures on purpose.

Real flight data (``shared/data/real``) is found by
:func:`gcs_monitor.evaluation.data.real_data_dir`: ``GCS_DATA_DIR``, else
``../shared/data/real`` beside the repository. Tests that need it take the ``real_data`` or
``real_data_file`` fixture and are skipped, with the variable named, when it is not there.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import pytest
from hypothesis import settings

from gcs_monitor.evaluation.data import missing_message, real_data_dir

settings.register_profile("ci", derandomize=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))


@pytest.fixture(scope="session")
def real_data() -> Path:
    """The real-data folder; skips the test when it is missing."""
    path = real_data_dir()
    if not path.is_dir():
        pytest.skip(missing_message(path, cli=False))
    return path


@pytest.fixture(scope="session")
def real_data_file(real_data: Path) -> Callable[[str], Path]:
    """``get(relative)``: a file (or folder) of the real data; skips the test when it is missing."""

    def get(relative: str) -> Path:
        path = real_data / relative
        if not path.exists():
            pytest.skip(missing_message(path, cli=False))
        return path

    return get
