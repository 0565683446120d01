"""Chen2020 observer design for a simulated airframe: LPV model and LMI gains, stored as data.

``gcs-monitor yaw-design --airframe NAME`` (or :func:`write_design`) linearises the simulator's
lateral dynamics at trim across the airframe's speed range, fits the LPV model affine in
``[V_eas, V_eas^2]`` (Chen2020 eq. 59) and solves the LMI of the observer gain ``L_1`` for each
monitorable gyro axis (:func:`gcs_monitor.filters.lpv_smo_design.design_l1`); the result goes
to ``gcs_monitor/families/yaw_rate/designs/<airframe>.json``, which the monitor loads (no
solver at monitor start).

Design values: Chen2020 sec. V for ``A_f = 0.01``, ``k_2 = 0.1``, ``k = 0.8`` and the sigmoid's
``delta = 0.01``; ours for the uncertainty distribution ``M_p`` and the bound on ``||L_1||``
(docs/papers-notes.md, Chen2020).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gcs_monitor.families.yaw_rate.design import (
    DesignParams,
    ObserverDesign,
    bands_to_dict,
    design_sensors,
    uncertainty_matrix,
)
from gcs_monitor.filters.lpv_smo_design import ClosedLoopBlock, design_l1
from gcs_monitor.models.lateral import STATES, LpvFitError, eas_from_tas
from sim_vehicle.dynamics.linearise import lateral_closed_loop, lateral_lpv, lateral_lti

DESIGN_DIR = Path(__file__).resolve().parents[2] / "families" / "yaw_rate" / "designs"


@dataclass(frozen=True, slots=True)
class Envelope:
    """Where an airframe's model is built: TAS range (m/s) at the reference altitude (m), and
    the altitude bands ``(centre, low, high)`` (m), each with its own model built at its
    centre over the same equivalent-airspeed range (the first band is the reference)."""

    tas_mps: tuple[float, float]
    alt_m: float
    bands_m: tuple[tuple[float, float, float], ...]
    n_points: int = 11

    def band_tas_mps(self, centre_m: float) -> tuple[float, float]:
        """The TAS range at ``centre_m`` with the reference range's equivalent airspeeds."""
        k = eas_from_tas(1.0, self.alt_m) / eas_from_tas(1.0, centre_m)
        return self.tas_mps[0] * k, self.tas_mps[1] * k


# transport: 160-360 kt (Wan2018's envelope; the presets fly 250 kt at 1000-1500 m) at 1500 m,
# bands of 3 km up to 12 km (the Wan2018 campaign flies 1000-9000 m): at a band's edge sqrt(rho)
# is 7-9 % off its centre's (a model built at 1500 m used at 8800 m: 33 %);
# uav: the Aerosonde's 18-35 m/s around its 25 m/s trim, one band to 3500 m
ENVELOPES = {"transport": Envelope((85.0, 185.0), 1500.0,
                                   ((1500.0, -500.0, 3000.0), (4500.0, 3000.0, 6000.0),
                                    (7500.0, 6000.0, 9000.0), (10500.0, 9000.0, 12000.0))),
             "uav": Envelope((18.0, 35.0), 1000.0, ((1000.0, -500.0, 3500.0),))}


def fit_summary(err: LpvFitError) -> dict[str, Any]:
    return {"rel_A": err.rel_A, "rel_B": err.rel_B, "eig_max_radps": err.eig_max_rad_s,
            "nrmse": err.nrmse.tolist(), "n_points": err.n_points}


def command_of(airframe: str) -> str:
    return f"gcs-monitor yaw-design --airframe {airframe}"


def make_band(airframe: str, band: tuple[float, float, float],
              p: DesignParams | None = None) -> tuple[ObserverDesign, LpvFitError]:
    """Linearise at the band's centre, fit and design (one altitude band)."""
    p = p or DesignParams()
    env = ENVELOPES[airframe]
    centre, lo, hi = band
    tas = env.band_tas_mps(centre)
    speeds = tuple(np.linspace(tas[0], tas[1], env.n_points).tolist())
    model, err, _ = lateral_lpv(airframe, speeds, centre)
    sensors, info = design_sensors(model, p)
    meta = {"command": command_of(airframe), "airframe": airframe, "alt_m": centre,
            "fit": fit_summary(err), "lmi": info,
            "params": {"A_f": p.A_f, "k2": p.k2, "k": p.k, "delta": p.delta,
                       "xi_weights": list(p.xi_weights), "l1_max": p.l1_max}}
    return ObserverDesign(model, sensors, meta, (lo, hi)), err


def make_design(airframe: str, p: DesignParams | None = None) -> tuple[ObserverDesign,
                                                                        LpvFitError]:
    """Linearise, fit and design for a simulated airframe at its reference altitude."""
    return make_band(airframe, ENVELOPES[airframe].bands_m[0], p)


def make_bands(airframe: str, p: DesignParams | None = None) -> list[ObserverDesign]:
    """The design of every altitude band of the airframe, the reference band first."""
    return [make_band(airframe, b, p)[0] for b in ENVELOPES[airframe].bands_m]


def write_design(airframe: str, out: Path | None = None) -> tuple[Path, list[ObserverDesign]]:
    """Make the designs of every band and write them (default: the shipped design file)."""
    bands = make_bands(airframe)
    path = out if out is not None else DESIGN_DIR / f"{airframe}.json"
    if path.is_dir():
        path = path / f"{airframe}.json"
    path.write_text(json.dumps(bands_to_dict(bands, {"command": command_of(airframe),
                                                     "airframe": airframe}), indent=1) + "\n")
    return path, bands


def closed_loop_bounds(airframe: str, design: ObserverDesign, *, n_points: int = 6,
                       l1_max: tuple[float, ...] = (0.3, 1.0)) -> list[list[Any]]:
    """Chen2020 eq. 58 with the simulator's autopilot as the controller: the L2-gain bound from
    xi to x_p of the autopilot's lateral loops on the corrected yaw rate coupled with the
    observer's sliding dynamics, on a grid of trim speeds (the autopilot's gains are scheduled
    on dynamic pressure, not affine in rho: a common P over the grid). Rows: uncertainty
    distribution, L_1 (the shipped one, or designed jointly under a bound), gamma, c_1 = 1/gamma.
    """

    env = ENVELOPES[airframe]
    ltis = [lateral_lti(airframe, v, env.alt_m)
            for v in np.linspace(env.tas_mps[0], env.tas_mps[1], n_points)]
    loops = [lateral_closed_loop(airframe, lt) for lt in ltis]
    A_p = [lt.A for lt in ltis]
    sd = design.sensors["r"]
    rows: list[list[Any]] = []
    for label, w in (("Chen2020 eq. 60 (p, r)", (0.0, 0.0, 1.0, 1.0)),
                     ("ours (beta x10, p, r)", DesignParams().xi_weights)):
        M = uncertainty_matrix(w)
        blocks = [ClosedLoopBlock(A, H, np.vstack([M, np.zeros((A.shape[0] - len(STATES),
                                                                M.shape[1]))]), C)
                  for A, H, C in loops]
        res = design_l1(A_p, sd.faulty, sd.A_f, M, l1_max=1.0, closed_loop=blocks,
                        L1_fixed=sd.L1)
        rows.append([label, "shipped", res.gamma, 1.0 / res.gamma, res.status])
        for lm in l1_max:
            res = design_l1(A_p, sd.faulty, sd.A_f, M, l1_max=lm, closed_loop=blocks)
            rows.append([label, f"joint, ||L_1|| <= {lm:g}: " + np.array2string(
                res.L1[0], precision=3, separator=", "), res.gamma, 1.0 / res.gamma,
                res.status])
    return rows
