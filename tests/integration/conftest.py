"""Fixtures of the end-to-end tests."""

from __future__ import annotations

import pytest

from tests.integration.support import base_packets as _base_packets


@pytest.fixture(scope="session")
def base_packets() -> list[tuple[int, bytes]]:
    """A fault-free simulated flight (tests/integration/support.py)."""
    return _base_packets()
