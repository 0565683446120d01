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

Chen2020's sliding-mode controller (sec. IV) is designed here as well (:func:`make_smc`, on a
stored observer design's LPV model: N at the 4 vertices of Omega, Phi, P_2 of eq. 45, the
modulation gain of eq. 46) with its closed-loop bound of eq. 58 (:func:`smc_bounds`); the
experiment that flies it is :mod:`~gcs_monitor.evaluation.papers.chen2020_smc`. Chen2020 gives
no controller values: they are ours (:class:`SmcParams`).
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gcs_monitor.evaluation.report import md_table
from gcs_monitor.families.yaw_rate.design import (
    DesignParams,
    ObserverDesign,
    bands_to_dict,
    design_sensors,
    uncertainty_matrix,
)
from gcs_monitor.filters.lpv_smc_design import (
    design_surface,
    lyapunov_p2,
    modulation_terms,
    sliding_blocks,
)
from gcs_monitor.filters.lpv_smo_design import ClosedLoopBlock, design_l1
from gcs_monitor.models.lateral import STATES, LateralLpv, LpvFitError, eas_from_tas
from gcs_monitor.models.lateral_tracking import B_VP_LATERAL, C_C_LATERAL, tracking_form
from sim_vehicle.autopilot.smc_lateral import SmcAutopilot, SmcGains
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


# ------------------------------------------------------------------------------------------------
# Chen2020 sec. IV: the sliding-mode controller
# ------------------------------------------------------------------------------------------------

EQ60 = (0.0, 0.0, 1.0, 1.0)  # Chen2020 eq. 60: xi on the roll- and yaw-rate rows


@dataclass(frozen=True, slots=True)
class SmcParams:
    """The controller's design values (all ours: Chen2020 gives none for its controller).

    decay_radps : decay rate of the sliding motion at every vertex (Assumption 4.1 with a
        margin), radius_radps : the modulus its eigenvalues stay within (the pole region),
        phi_radps : ``Phi = -phi I`` (eq. 42), the reaching rate of s^. Chosen (1.5, 6, 2) for
        the lowest fault-free sideslip RMSE (the fault cases were not the criterion: two other
        designs below keep the uncorrected slow drift near fault-free by themselves, so how
        much the correction adds depends on the design). Flown on the fault-free and the
        slow-drift S-turn (seed 20, sigma 1 m/s: the evaluation
        flights themselves, no held-out seed), roll / sideslip RMSE over 30-120 s, fault-free |
        slow drift uncorrected | corrected [deg]: (0.8, 3, 2) 10.4/1.56 | 46/2.16 | 10.8/1.76;
        (1.2, 4, 2) 11.2/1.14 | 24.0/1.82 | 11.2/1.14; (1.5, 6, 2) 11.2/1.04 | 20.9/1.70 |
        11.2/1.05; (1.5, 6, 4) 10.3/1.34 | 10.6/1.19 | 10.4/1.29; (2, 8, 2) 10.5/1.15 |
        10.9/1.06 | 10.7/1.10. The aileron saturates in every one of them in the sideslip
        phases (docs/results.md), which makes the ranking erratic. A faster sliding motion
        also lowers the eq. 58 bound (0.8 1/s: 5.29 with the shipped L_1; 1.5: 4.88; 3: 4.80)
    eta1_radps2 : bound on ||xi|| (eq. 15), rad/s^2 on the roll/yaw-rate rows: light turbulence
        and the linear model's mismatch in the turns
    chi_radps : bound on ||e~_1|| (eq. 18): the observer's fault-estimation error (rad/s)
    eta2_radps2 : eta_2 of eq. 46
    delta : sigmoid smoothing of eq. 44 (the unit of P_2 s^, rad/s)
    prefilter_s : command pre-filter time constants (eq. 26), roll and sideslip (the roll
        command's rate is also capped: ``sim_vehicle/autopilot/smc_lateral.py``)
    """

    decay_radps: float = 1.5
    radius_radps: float = 6.0
    phi_radps: float = 2.0
    eta1_radps2: float = 0.02
    chi_radps: float = 0.005
    eta2_radps2: float = 0.01
    delta: float = 0.01
    prefilter_s: tuple[float, float] = (1.0, 0.5)


def vertex_matrices(model: LateralLpv) -> list[tuple[np.ndarray, np.ndarray]]:
    """``(A_p, B_p)`` at the 4 vertices of Omega."""
    return [model.at_rho(*r) for r in model.vertices()]


def make_smc(design: ObserverDesign, p: SmcParams | None = None) -> tuple[SmcGains,
                                                                          dict[str, Any]]:
    """The SMC's design on ``design``'s model and its yaw-rate observer (for eq. 46)."""
    p = p or SmcParams()
    verts = vertex_matrices(design.model)
    forms = [tracking_form(A, B) for A, B in verts]
    surf = design_surface(forms, decay=p.decay_radps, radius=p.radius_radps)
    if not np.all(np.isfinite(surf.N)):
        raise RuntimeError(f"sliding-surface LMI failed: {surf.status}")
    Phi = -p.phi_radps * np.eye(2)
    P2 = lyapunov_p2(Phi)
    sd = design.sensors["r"]
    m, h = modulation_terms([A for A, _ in verts], forms, surf.N, sd.faulty, sd.A_f, sd.L1,
                            uncertainty_matrix(EQ60), C_C_LATERAL)
    K = m * p.eta1_radps2 + h * p.chi_radps + p.eta2_radps2  # eq. 46
    gains = SmcGains(surf.N, Phi, P2, K, p.delta, p.prefilter_s, C_C_LATERAL.copy(),
                     B_VP_LATERAL.copy())
    b_res = max(float(np.linalg.norm(B[1]) / np.linalg.norm(B[2:])) for _, B in verts)
    info = {"params": asdict(p), "status": surf.status, "solver": surf.solver,
            "max_real": surf.max_real, "max_abs": surf.max_abs, "m": m, "h": h, "K": K,
            "beta_row_of_B": b_res}
    return gains, info


def smc_bounds(design: ObserverDesign, gains: SmcGains,
               l1_max: tuple[float, ...] = (0.3, 1.0)) -> list[list[Any]]:
    """Chen2020 eq. 58 with the SMC: rows (L_1, gamma, c_1, status) for the shipped ``L_1`` and
    ``L_1`` designed jointly with the fixed ``N`` under each bound."""
    verts = vertex_matrices(design.model)
    forms = [tracking_form(A, B) for A, B in verts]
    M = uncertainty_matrix(EQ60)
    sd = design.sensors["r"]
    blocks = sliding_blocks(forms, gains.N, sd.faulty, M, gains.C_c)
    A_p = [A for A, _ in verts]
    res = design_l1(A_p, sd.faulty, sd.A_f, M, l1_max=1.0, closed_loop=blocks, L1_fixed=sd.L1)
    rows: list[list[Any]] = [["shipped", res.gamma, 1.0 / res.gamma, res.status]]
    for lm in l1_max:
        res = design_l1(A_p, sd.faulty, sd.A_f, M, l1_max=lm, closed_loop=blocks)
        rows.append([f"joint, ||L_1|| <= {lm:g}: " + np.array2string(
            res.L1[0], precision=3, separator=", "), res.gamma, 1.0 / res.gamma, res.status])
    return rows


def design_text(design: ObserverDesign, gains: SmcGains, info: dict[str, Any]) -> str:
    """The SMC design and its eq. 58 bounds as Markdown."""
    rows = smc_bounds(design, gains)
    p = info["params"]
    return ("Sliding-mode controller (Chen2020 sec. IV) on the transport's LPV model (4 vertices "
            f"of Omega): N (fixed) with sliding motion decay >= {p['decay_radps']:g} 1/s and "
            f"|eig| <= {p['radius_radps']:g} 1/s ({info['solver']}, {info['status']}; worst max "
            f"Re eig {info['max_real']:.3f} 1/s, worst |eig| {info['max_abs']:.3f} 1/s), "
            f"Phi = -{p['phi_radps']:g} I, P_2 = {gains.P2[0, 0]:.4g} I (eq. 45), modulation "
            f"K = m eta_1 + h chi + eta_2 = {info['m']:.3f} x {p['eta1_radps2']:g} + "
            f"{info['h']:.3f} x {p['chi_radps']:g} + {p['eta2_radps2']:g} = {info['K']:.4f} "
            f"rad/s^2 (eq. 46), sigmoid delta {p['delta']:g}; the rudder's side force left out "
            f"of B_c (beta row of B_p / ||p, r rows|| <= {info['beta_row_of_B']:.3f}).\n\nN = "
            + np.array2string(gains.N, precision=4, separator=", ").replace("\n", "")
            + "\n\nClosed loop (eq. 58: the SMC's sliding motion with the observer's sliding "
            "dynamics, xi -> x_p, Chen2020 eq. 60 uncertainty, 4 vertices, common P; Chen2020 "
            "reports 1.2918; the PID autopilot gives 4.1 with the shipped L_1, 1.26 joint with "
            "||L_1|| <= 1):\n\n"
            + md_table(["L_1", "L2-gain bound xi -> x_p", "c_1 = 1/gamma", "status"], rows)
            + "\n")


class SmcFactory:
    """``ftc_run(autopilot=...)``: the SMC autopilot for a simulation (picklable)."""

    def __init__(self, model: LateralLpv, gains: SmcGains) -> None:
        self.model = model
        self.gains = gains

    def __call__(self, sim: Any) -> SmcAutopilot:
        return SmcAutopilot(sim.airframe, sim.trim, sim.autopilot.g, self.model, self.gains)
