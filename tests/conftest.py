"""Test-wide settings.

Hypothesis draws its examples from a fixed seed (``derandomize``), so the same commit gives the
same test run, as the project asks of every random draw. ``HYPOTHESIS_PROFILE=explore pytest``
draws new examples on every run, to look for failures on purpose.
"""

from __future__ import annotations

import os

from hypothesis import settings

settings.register_profile("ci", derandomize=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))
