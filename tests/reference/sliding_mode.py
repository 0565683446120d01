"""Numpy reference of the Levant differentiator kernel (Atmaca2025 eqs. 47-50;
``filters/_sliding_mode_jit.py``)."""

from __future__ import annotations

import numpy as np

from gcs_monitor.core.types import Mat, Vec
from gcs_monitor.filters.sliding_mode import HosmState


def hosm_step_reference(s: HosmState, f: Vec, lambdas: Mat, dt_s: float) -> HosmState:
    """:func:`gcs_monitor.filters.sliding_mode.hosm_step` in numpy (eqs. 47-50, explicit Euler),
    all channels at once."""
    z0, z1, z2, z3 = s.z
    e0 = z0 - f
    v0 = -lambdas[0] * np.abs(e0) ** 0.75 * np.sign(e0) + z1
    e1 = z1 - v0
    v1 = -lambdas[1] * np.abs(e1) ** (2.0 / 3.0) * np.sign(e1) + z2
    e2 = z2 - v1
    v2 = -lambdas[2] * np.sqrt(np.abs(e2)) * np.sign(e2) + z3
    v3 = -lambdas[3] * np.sign(z3 - v2)
    return HosmState(z=np.stack([z0 + v0 * dt_s, z1 + v1 * dt_s, z2 + v2 * dt_s, z3 + v3 * dt_s]))
