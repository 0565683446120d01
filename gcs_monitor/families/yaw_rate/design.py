"""The stored observer designs: an LPV lateral model and its sliding-mode observer gains.

A design file (JSON) holds the model (:class:`~gcs_monitor.models.lateral.LateralLpv`), its fit
error, one :class:`~gcs_monitor.filters.lpv_smo.SmoDesign` per monitorable sensor (``"r"``,
``"p"``, ...; each with its L2-gain bound) and the command that produced it. Designs of the
simulator's airframes ship in ``designs/<airframe>.json`` (written by
``gcs-monitor yaw-design --airframe NAME``); a real aircraft's comes from its clean flights
(``identify_lateral_model`` then the same LMI design). Loading a design needs neither the
simulator nor an SDP solver.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

from gcs_monitor.filters.lpv_smo import SmoDesign
from gcs_monitor.models.lateral import STATES, LateralLpv

DESIGN_VERSION = 1


@dataclass(frozen=True, slots=True)
class ObserverDesign:
    """One aircraft's stored design.

    model : the LPV lateral model
    sensors : per lateral sensor name (an element of :data:`STATES`), its observer design
    meta : provenance (command, fit error, solver, bounds)
    """

    model: LateralLpv
    sensors: dict[str, SmoDesign]
    meta: dict[str, Any]

    def to_dict(self) -> dict[str, Any]:
        return {"version": DESIGN_VERSION, "model": self.model.to_dict(),
                "sensors": {k: v.to_dict() for k, v in self.sensors.items()}, "meta": self.meta}

    @staticmethod
    def from_dict(d: dict[str, Any]) -> ObserverDesign:
        if d.get("version") != DESIGN_VERSION:
            raise ValueError(f"yaw-rate design version {d.get('version')}, expected "
                             f"{DESIGN_VERSION}")
        sensors = {k: SmoDesign.from_dict(v) for k, v in d["sensors"].items()}
        for k, v in sensors.items():
            if k not in STATES or v.faulty != (STATES.index(k),):
                raise ValueError(f"design for sensor {k!r} has faulty outputs {v.faulty}")
        return ObserverDesign(LateralLpv.from_dict(d["model"]), sensors, dict(d.get("meta", {})))


def builtin_designs() -> list[str]:
    """Names of the designs shipped with the monitor (the simulator's airframes)."""
    d = resources.files("gcs_monitor.families.yaw_rate") / "designs"
    return sorted(p.name[:-5] for p in d.iterdir() if p.name.endswith(".json"))


def load_design(name_or_path: str) -> ObserverDesign:
    """A shipped design by name (``"transport"``, ``"uav"``) or a design file by path."""
    if name_or_path.endswith(".json"):
        text = Path(name_or_path).read_text()
    else:
        res = resources.files("gcs_monitor.families.yaw_rate") / "designs" / \
            f"{name_or_path}.json"
        if not res.is_file():
            raise ValueError(f"unknown yaw-rate design {name_or_path!r}; shipped: "
                             f"{builtin_designs()} (or give a .json path)")
        text = res.read_text()
    return ObserverDesign.from_dict(json.loads(text))
