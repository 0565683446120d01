"""Named experiments for ``gcs-monitor evaluate --experiment NAME``.

The evaluation package is the one part of gcs_monitor that drives the simulator (sim_vehicle):
evaluation needs ground truth by definition. Nothing else in gcs_monitor imports sim_vehicle.
"""

from __future__ import annotations

import importlib
import re
from collections.abc import Callable
from pathlib import Path

Experiment = Callable[[Path, int, bool], str]
MODULES = ("gcs_monitor.evaluation.sim_checks", "gcs_monitor.evaluation.imu",
           "gcs_monitor.evaluation.imu_real", "gcs_monitor.evaluation.wan2018",
           "gcs_monitor.evaluation.harness")


def experiments() -> dict[str, Experiment]:
    """Every experiment of every evaluation module that defines ``experiments()``."""
    out: dict[str, Experiment] = {}
    for name in MODULES:
        try:
            mod = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name == name:
                continue
            raise
        fn = getattr(mod, "experiments", None)
        if fn is not None:
            out.update(fn())
    return out


def summary(fn: Experiment, width: int = 100) -> str:
    """An experiment's docstring, first paragraph, on one line of at most ``width`` characters
    (reST roles dropped)."""
    doc = (fn.__doc__ or "").strip().split("\n\n")[0]
    text = re.sub(r":\w+:`([^`]*)`", r"\1", " ".join(doc.split())).replace("``", "`")
    if len(text) <= width:
        return text
    return text[: width - 1].rsplit(" ", 1)[0] + " ..."
