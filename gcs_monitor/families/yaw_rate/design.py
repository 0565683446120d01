"""The stored observer designs: an LPV lateral model and its sliding-mode observer gains.

A design (JSON) holds the model (:class:`~gcs_monitor.models.lateral.LateralLpv`), its fit
error, one :class:`~gcs_monitor.filters.lpv_smo.SmoDesign` per monitorable sensor (``"r"``,
``"p"``, ...; each with its L2-gain bound), the pressure-altitude band it holds in and the
command that produced it. A design file holds one design, or several altitude bands
(``{"bands": [design, ...]}``): Chen2020 eq. 59 schedules on ``V_eas`` alone, which holds at one
altitude only. At a given ``V_eas`` the damping derivatives (``L_p``, ``N_r``, ...) scale with
``rho V_tas = V_eas sqrt(rho rho_0)`` and the kinematic terms with ``1 / V_tas``, so a model
built at 1500 m reconstructs a fault of 0.4 deg/s in the S-turns of a fault-free flight at
8800 m (docs/papers-notes.md, Chen2020); the shipped transport design has one LPV model and
observer per band of 3 km, each built at its band's centre over the same ``V_eas`` range.
Designs of the simulator's airframes ship in ``designs/<airframe>.json`` (written by
``gcs-monitor yaw-design --airframe NAME``); a real aircraft's comes from its clean flights
(:func:`~gcs_monitor.models.lateral.identify_lateral_model`, then :func:`design_observer`,
the same LMI design, which needs cvxpy: the ``design`` extra). Loading a design needs neither
the simulator nor an SDP solver.
"""

from __future__ import annotations

import json
import math
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
    alt_range_m : the pressure altitudes (m) the model holds in; unbounded for a model
        identified from flights (it holds where they flew: its file says which)
    """

    model: LateralLpv
    sensors: dict[str, SmoDesign]
    meta: dict[str, Any]
    alt_range_m: tuple[float, float] = (-math.inf, math.inf)

    def to_dict(self) -> dict[str, Any]:
        d = {"version": DESIGN_VERSION, "model": self.model.to_dict(),
             "sensors": {k: v.to_dict() for k, v in self.sensors.items()}, "meta": self.meta}
        if all(math.isfinite(a) for a in self.alt_range_m):
            d["alt_range_m"] = list(self.alt_range_m)
        return d

    @staticmethod
    def from_dict(d: dict[str, Any]) -> ObserverDesign:
        if d.get("version") != DESIGN_VERSION:
            raise ValueError(f"yaw-rate design version {d.get('version')}, expected "
                             f"{DESIGN_VERSION}")
        sensors = {k: SmoDesign.from_dict(v) for k, v in d["sensors"].items()}
        for k, v in sensors.items():
            if k not in STATES or v.faulty != (STATES.index(k),):
                raise ValueError(f"design for sensor {k!r} has faulty outputs {v.faulty}")
        lo, hi = d.get("alt_range_m", (-math.inf, math.inf))
        return ObserverDesign(LateralLpv.from_dict(d["model"]), sensors, dict(d.get("meta", {})),
                              (float(lo), float(hi)))

    def holds_at(self, alt_m: float) -> bool:
        """Whether the model holds at this pressure altitude."""
        lo, hi = self.alt_range_m
        return lo <= alt_m < hi


def bands_to_dict(bands: list[ObserverDesign], meta: dict[str, Any]) -> dict[str, Any]:
    """A design file of several altitude bands (each a design dict), lowest first."""
    return {"bands": [b.to_dict() for b in bands], "meta": meta}


def builtin_designs() -> list[str]:
    """Names of the designs shipped with the monitor (the simulator's airframes)."""
    d = resources.files("gcs_monitor.families.yaw_rate") / "designs"
    return sorted(p.name[:-5] for p in d.iterdir() if p.name.endswith(".json"))


def load_design(name_or_path: str) -> ObserverDesign:
    """The reference design of a shipped airframe (``"transport"``, ``"uav"``) or a design
    file: its first altitude band (the one the airframe's evaluation flies in)."""
    return load_bands(name_or_path)[0]


def load_bands(name_or_path: str) -> list[ObserverDesign]:
    """Every altitude band of a shipped design by name or of a design file by path, lowest
    first; a file of one design is one band."""
    if name_or_path.endswith(".json"):
        text = Path(name_or_path).read_text()
    else:
        res = resources.files("gcs_monitor.families.yaw_rate") / "designs" / \
            f"{name_or_path}.json"
        if not res.is_file():
            raise ValueError(f"unknown yaw-rate design {name_or_path!r}; shipped: "
                             f"{builtin_designs()} (or give a .json path)")
        text = res.read_text()
    d = json.loads(text)
    if "bands" not in d:
        return [ObserverDesign.from_dict(d)]
    bands = sorted((ObserverDesign.from_dict(b) for b in d["bands"]),
                   key=lambda b: b.alt_range_m[0])
    if not bands:
        raise ValueError(f"yaw-rate design {name_or_path!r} has no band")
    for a, b in zip(bands, bands[1:], strict=False):
        if a.alt_range_m[1] > b.alt_range_m[0]:
            raise ValueError(f"yaw-rate design {name_or_path!r}: altitude bands "
                             f"{a.alt_range_m} and {b.alt_range_m} overlap")
    return bands


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
