"""Optional compiled kernels: import a module on first use, or None when it cannot be imported.

The numba kernels (``*_jit.py``) are imported lazily so that importing the models and filters
stays light; without numba every caller falls back to its numpy reference path.
"""

from __future__ import annotations

import functools
import importlib
from types import ModuleType


@functools.cache
def optional_module(name: str) -> ModuleType | None:
    """The module ``name``, imported once; None if it (or numba under it) is not installed."""
    try:
        return importlib.import_module(name)
    except ImportError:  # pragma: no cover - numba missing
        return None
