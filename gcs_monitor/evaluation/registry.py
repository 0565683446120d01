"""Named experiments for ``gcs-monitor evaluate --experiment NAME`` (``--list`` describes them).

Each module below defines ``experiments()``: name -> ``fn(out_dir, jobs, quick)`` returning
Markdown; the modules on real flight data define ``real_data_experiments()`` instead, whose
functions also take the real-data folder. The registry hands every experiment out with the same
three arguments and resolves that folder (:func:`~gcs_monitor.evaluation.data.real_data_dir`:
``--data-dir``, ``GCS_DATA_DIR``, ``../shared/data/real``) when a real-data experiment runs.

The evaluation package is the one part of gcs_monitor that drives the simulator (sim_vehicle):
evaluation needs ground truth by definition. Nothing else in gcs_monitor imports sim_vehicle.
"""

from __future__ import annotations

import functools
import re
from collections.abc import Callable
from pathlib import Path

from gcs_monitor.evaluation import campaign, sim_checks
from gcs_monitor.evaluation.data import real_data_dir
from gcs_monitor.evaluation.papers import (
    actuators,
    actuators_alfa,
    atmaca2025,
    chen2020,
    chen2020_smc,
    imu_detection,
    lu2016,
    lu2016_real,
    lu2017,
    real_flights,
    robustness,
    wan2018,
    wan2018_real,
)

Experiment = Callable[[Path, int, bool], str]  # (out_dir, jobs, quick) -> Markdown
RealDataExperiment = Callable[[Path, int, bool, Path], str]  # ... and the real-data folder

SIMULATED: tuple[Callable[[], dict[str, Experiment]], ...] = (
    sim_checks.experiments, lu2016.experiments, atmaca2025.experiments,
    imu_detection.experiments, wan2018.experiments, campaign.experiments,
    robustness.experiments, lu2017.experiments, chen2020.experiments,
    chen2020_smc.experiments,
    actuators.experiments)
REAL_DATA: tuple[Callable[[], dict[str, RealDataExperiment]], ...] = (
    lu2016_real.real_data_experiments, wan2018_real.real_data_experiments,
    real_flights.real_data_experiments, actuators_alfa.real_data_experiments)


def _on_data(fn: RealDataExperiment, data_dir: Path | None) -> Experiment:
    """``fn`` with the real-data folder resolved when it runs (so ``--list`` needs no data)."""

    @functools.wraps(fn)
    def run(out_dir: Path, jobs: int = 1, quick: bool = False) -> str:
        return fn(out_dir, jobs, quick, real_data_dir(data_dir))

    return run


def experiments(data_dir: Path | None = None) -> dict[str, Experiment]:
    """Every experiment by name; the real-data ones read ``data_dir`` (``--data-dir``; None:
    ``GCS_DATA_DIR`` or the default, see :func:`~gcs_monitor.evaluation.data.real_data_dir`)."""
    out: dict[str, Experiment] = {}
    for hook in SIMULATED:
        out.update(hook())
    for real in REAL_DATA:
        out.update({name: _on_data(fn, data_dir) for name, fn in real().items()})
    return out


def summary(fn: Experiment, width: int = 100) -> str:
    """An experiment's docstring, first paragraph, on one line of at most ``width`` characters
    (reST roles dropped)."""
    doc = (fn.__doc__ or "").strip().split("\n\n")[0]
    text = re.sub(r":\w+:`([^`]*)`", r"\1", " ".join(doc.split())).replace("``", "`")
    if len(text) <= width:
        return text
    return text[: width - 1].rsplit(" ", 1)[0] + " ..."
