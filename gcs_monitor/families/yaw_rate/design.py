"""The stored observer designs: an LPV lateral model and its sliding-mode observer gains.

A design file (JSON) holds the model (:class:`~gcs_monitor.models.lateral.LateralLpv`), its fit
error, one :class:`~gcs_monitor.filters.lpv_smo.SmoDesign` per monitorable sensor (``"r"``,
``"p"``, ...; each with its L2-gain bound) and the command that produced it. Designs of the
simulator's airframes ship in ``designs/<airframe>.json`` (written by
``gcs-monitor yaw-design --airframe NAME``); a real aircraft's comes from its clean flights
(:func:`~gcs_monitor.models.lateral.identify_lateral_model`, then :func:`design_observer`,
the same LMI design, which needs cvxpy: the ``design`` extra). Loading a design needs neither
the simulator nor an SDP solver.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from gcs_monitor.filters.lpv_smo import SmoDesign
from gcs_monitor.filters.lpv_smo_design import a11_margin, design_l1
from gcs_monitor.models.lateral import STATES, LateralLpv, LpvFitError

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


@dataclass(frozen=True, slots=True)
class DesignParams:
    """The design values (Chen2020 sec. V where it gives them)."""

    A_f: float = 0.01  # Chen2020 sec. V
    k2: float = 0.1  # Chen2020 sec. V
    k: float = 0.8  # Chen2020 sec. V (flown; 1.2 was the open-loop optimum of Fig. 2)
    delta: float = 0.01  # Chen2020 sec. V, sigmoid smoothing
    # ours: uncertainty channels beta, p, r with weights (Chen2020 eq. 60: p, r only)
    xi_weights: tuple[float, float, float, float] = (0.0, 10.0, 1.0, 1.0)
    l1_max: float = 0.3  # ours: bound on ||L_1|| (noise through G_n = [-L; I])


def uncertainty_matrix(weights: tuple[float, ...]) -> np.ndarray:
    """``M_p`` with one column per weighted state channel (Chen2020 eq. 60 is weights
    (0, 0, 1, 1))."""
    cols = [i for i, w in enumerate(weights) if w > 0.0]
    M = np.zeros((len(STATES), len(cols)))
    for j, i in enumerate(cols):
        M[i, j] = weights[i]
    return M


def design_sensors(model: LateralLpv, p: DesignParams,
                   sensors: tuple[str, ...] = ("r", "p")) -> tuple[dict[str, SmoDesign],
                                                                   dict[str, Any]]:
    """The LMI design of every sensor's observer on ``model``'s vertices."""
    verts = [model.at_rho(*r)[0] for r in model.vertices()]
    Mp = uncertainty_matrix(p.xi_weights)
    A_f = np.array([[p.A_f]])
    out: dict[str, SmoDesign] = {}
    info: dict[str, Any] = {}
    for s in sensors:
        faulty = (STATES.index(s),)
        res = design_l1(verts, faulty, A_f, Mp, l1_max=p.l1_max)
        if not np.all(np.isfinite(res.L1)):
            raise RuntimeError(f"LMI design for sensor {s} failed: {res.status}")
        out[s] = SmoDesign(faulty, A_f, p.k2, res.L1, p.k, p.delta, res.gamma)
        info[s] = {"gamma": res.gamma, "status": res.status, "solver": res.solver,
                   "a11_margin_radps": max(a11_margin(v, faulty, A_f, res.L1) for v in verts)}
    return out, info


def design_observer(model: LateralLpv, *, params: DesignParams | None = None,
                    fit: LpvFitError | None = None, command: str = "",
                    sensors: tuple[str, ...] = ("r", "p")) -> ObserverDesign:
    """The stored design of an aircraft from its LPV model (the simulator's linearisation, or
    :func:`~gcs_monitor.models.lateral.identify_lateral_model` on its clean flights): the LMI
    gains of every sensor's observer and the provenance. Write it with
    ``json.dumps(design.to_dict())`` and point ``[yaw_rate] design`` at the file."""
    p = params or DesignParams()
    obs, info = design_sensors(model, p, sensors)
    meta: dict[str, Any] = {"command": command, "source": model.source, "lmi": info,
                            "params": {"A_f": p.A_f, "k2": p.k2, "k": p.k, "delta": p.delta,
                                       "xi_weights": list(p.xi_weights), "l1_max": p.l1_max}}
    if fit is not None:
        meta["fit"] = {"rel_A": fit.rel_A, "rel_B": fit.rel_B, "eig_max_radps": fit.eig_max_rad_s,
                       "nrmse": fit.nrmse.tolist(), "n_points": fit.n_points}
    return ObserverDesign(model, obs, meta)
