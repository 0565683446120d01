"""Per-sample cost of the Wan2018 real-time CMHE against CasADi on the same N = 3 problem.

Runs the CMHE (its numba kernels) over a synthetic 250 kt flight with a
three-CAS runaway (so the wind bounds become active), records every horizon problem
(arrival prior, y, output mask, Theta, t_s), and re-solves each with CasADi: IPOPT and
sqpmethod + qrqp, both warm-started from their own previous (shifted) solution. Prints median
and p99 per-sample times, the ratio t_CMHE / t_solver, and the deviation of x_hat_{k|k} from
ours (for CasADi: the converged NLP against our one real-time iteration; for the numpy reference
of the CMHE, tests/reference/mhe.py: round-off). Targets: CMHE at least 10x faster than IPOPT,
and no slower than sqpmethod + qrqp (median ratio <= 1).

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_mhe.py [--samples 600] [--lateral]

``--lateral`` runs the estimator as the monitor's default configuration does, with bank and
sideslip in eqs. 12-15 (Theta of 8; the synthetic flight is wings level, so the terms' values
are the paper's, but the kernel and the CasADi problem evaluate the general trigonometry).

Wan2018 sec. V-C reports 5.8 ms per sample on the Airbus FCC (SAO implementation).
"""

from __future__ import annotations

import argparse
import logging
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "helpers"))
sys.path.insert(0, str(ROOT))  # tests.reference (the numpy reference row)

import airdata_synth as synth  # noqa: E402

from gcs_monitor.core import constants as c  # noqa: E402
from gcs_monitor.core.units import KT2MPS  # noqa: E402
from gcs_monitor.families.airdata.estimator import AirDataEstimator, AirDataEstimatorConfig  # noqa: E402

log = logging.getLogger("bench_mhe")
PAPER_MS = 5.8


def record_problems(
    n_samples: int, *, reference: bool = False, lateral: bool = False
) -> tuple[list[dict[str, np.ndarray]], np.ndarray, np.ndarray]:
    """Run the CMHE estimator, timing mhe_step (``reference``: its numpy reference,
    tests/reference/mhe.py, instead); return horizon problems and our x_hat_{k|k}."""
    faults = tuple(synth.SensorFault("cas", i, 15.0, "runaway", -15.0 * KT2MPS) for i in range(3))
    dur = n_samples * 0.05 + 2.0
    run = synth.generate(synth.SynthConfig(duration_s=dur, faults=faults), np.random.default_rng(3))
    est = AirDataEstimator(AirDataEstimatorConfig(lateral_terms=lateral), variant="cmhe")
    probs: list[dict[str, np.ndarray]] = []
    times: list[float] = []
    x_ours: list[np.ndarray] = []
    import gcs_monitor.families.airdata.estimator as mod

    orig = mod.mhe_step
    step = orig
    if reference:
        from tests.reference.mhe import mhe_step_reference

        step = mhe_step_reference

    def timed(*args, **kw):  # type: ignore[no-untyped-def]
        prev = args[0]
        t0 = time.perf_counter()
        out = step(*args, **kw)
        times.append(time.perf_counter() - t0)
        s = out[0]
        if s.n == prev.n:  # full horizon: prior = x_hat_{l|k-1} = previous node 1
            probs.append(
                dict(
                    prior=prev.x[1].copy(),
                    y=s.y.copy(),
                    mask=s.y_mask.copy(),
                    theta=s.theta.copy(),
                    dt=s.dt_s[:-1].copy(),
                )
            )
            x_ours.append(s.x.copy())
        return out

    mod.mhe_step = timed
    try:
        for fr in run.frames:
            est.step(fr)
    finally:
        mod.mhe_step = orig
    return probs, np.array(times[20:]), np.array(x_ours)  # skip JIT warm-up samples


def build_casadi(est: AirDataEstimator, solver: str):  # type: ignore[no-untyped-def]
    import casadi as ca

    n, nx, nu = 3, 4, 4
    g = c.GRAVITY_STD_MPS2
    k_cas = 5.0 * c.ISA_GAMMA * c.ISA_R_JPKGK
    gas_exp = -g / (c.ISA_R_JPKGK * c.ISA_LAPSE_KPM)
    X = ca.SX.sym("X", nx, n)
    U = ca.SX.sym("U", nu, n - 1)
    prior = ca.SX.sym("prior", nx)
    Y = ca.SX.sym("Y", 4, n)
    M = ca.SX.sym("M", 4, n)
    n_th = 8 if est.cfg.lateral_terms else 6  # Theta (+ [phi, beta]: models.airdata.lateral)
    TH = ca.SX.sym("TH", n_th, n)
    DT = ca.SX.sym("DT", n - 1)

    wacc_on = est.model.params.wind_accel_in_alpha

    def phi_beta(th):  # (0, 0): Wan2018's wings-level forms exactly
        return (th[6], th[7]) if n_th == 8 else (0, 0)

    def f(x, u, th, dt):  # Wan2018 eq. 20 (+ the eq. 8 wind-acceleration term, as the model)
        a, (phi, _) = x[0], phi_beta(th)
        sa, ca_, st, ct = ca.sin(a), ca.cos(a), ca.sin(th[1]), ca.cos(th[1])
        fa = -th[3] * sa + th[4] * ca_ + g * (ca_ * ct * ca.cos(phi) + sa * st)
        fv = th[3] * ca_ + th[4] * sa + g * (sa * ct * ca.cos(phi) - ca_ * st)
        wacc = (u[2] * ca.sin(a - th[1]) - u[3] * ca.cos(a - th[1])) / th[0] if wacc_on else 0
        return x + dt * (ca.vertcat(fa / th[0] + th[2] + wacc, fv, 0, 0) + u)

    def h(x, th):  # Wan2018 eqs. 11, 15, 16
        d = x[0] - th[1]
        vt = th[0] - x[2] * ca.cos(d) - x[3] * ca.sin(d)
        t_k = c.ISA_T0_K + c.ISA_LAPSE_KPM * th[5]
        pbar = (1 + c.ISA_LAPSE_KPM * th[5] / c.ISA_T0_K) ** gas_exp
        yy = ((1 + vt**2 / (k_cas * t_k)) ** 3.5 - 1) * pbar + 1
        vc = ca.sqrt(k_cas * c.ISA_T0_K) * ca.sqrt(yy ** (1 / 3.5) - 1)
        phi, beta = phi_beta(th)
        a, cb = x[0], ca.cos(beta)
        sg = (ca.cos(a) * cb * ca.sin(th[1])
              - (ca.sin(phi) * ca.sin(beta) + ca.cos(phi) * ca.sin(a) * cb) * ca.cos(th[1]))
        return ca.vertcat(x[1], th[0] * sg - x[3], x[0], vc)

    w = est.weights
    dxp = X[:, 0] - prior
    J = 0.5 * ca.sumsqr(dxp / np.sqrt(w.p_diag))
    cons = []
    for i in range(n):
        r = (Y[:, i] - h(X[:, i], TH[:, i])) * M[:, i]
        J += 0.5 * ca.sumsqr(r / np.sqrt(w.r_diag))
        if i < n - 1:
            J += 0.5 * ca.sumsqr(U[:, i] / np.sqrt(w.q_diag))
            cons.append(X[:, i + 1] - f(X[:, i], U[:, i], TH[:, i], DT[i]))
    z = ca.vertcat(ca.vec(X), ca.vec(U))
    p = ca.vertcat(prior, ca.vec(Y), ca.vec(M), ca.vec(TH), DT)
    nlp = {"x": z, "p": p, "f": J, "g": ca.vertcat(*cons)}
    if solver == "ipopt":
        opts = {
            "print_time": False,
            "ipopt": {"print_level": 0, "sb": "yes", "warm_start_init_point": "yes", "tol": 1e-8},
        }
        S = ca.nlpsol("s", "ipopt", nlp, opts)
    else:
        opts = {
            "print_time": False,
            "print_header": False,
            "print_iteration": False,
            "print_status": False,
            "qpsol": "qrqp",
            "hessian_approximation": "exact",
            "qpsol_options": {"print_iter": False, "print_header": False, "error_on_fail": False},
            "tol_pr": 1e-8,
            "tol_du": 1e-8,
            "max_iter": 50,
        }
        S = ca.nlpsol("s", "sqpmethod", nlp, opts)
    b = est.bounds
    lbx = np.concatenate(
        [
            np.tile(np.where(np.isfinite(b.x_lb), b.x_lb, -1e20), n),
            np.tile(np.where(np.isfinite(b.u_lb), b.u_lb, -1e20), n - 1),
        ]
    )
    ubx = -lbx
    return S, lbx, ubx


def run_casadi(
    est: AirDataEstimator, probs: list[dict[str, np.ndarray]], solver: str
) -> tuple[np.ndarray, np.ndarray]:
    S, lbx, ubx = build_casadi(est, solver)
    n, nx = 3, 4
    z = None
    times, xs = [], []
    for pr in probs:
        p = np.concatenate(
            [
                pr["prior"],
                pr["y"].ravel(),
                pr["mask"].ravel(),  # casadi vec: column-major
                pr["theta"].ravel(),
                pr["dt"],
            ]
        )
        if z is None:
            z0 = np.concatenate([np.tile(pr["prior"], n), np.zeros(4 * (n - 1))])
        else:  # shift the previous solution, u_hat = 0 for the new interval
            X = z[: nx * n].reshape(n, nx)
            Uo = z[nx * n :].reshape(n - 1, 4)
            z0 = np.concatenate([X[1:].ravel(), X[-1], Uo[1:].ravel(), np.zeros(4)])
        z0 = np.clip(z0, lbx, ubx)
        t0 = time.perf_counter()
        sol = S(x0=z0, p=p, lbx=lbx, ubx=ubx, lbg=0, ubg=0)
        times.append(time.perf_counter() - t0)
        z = np.array(sol["x"]).ravel()
        xs.append(z[: nx * n].reshape(n, nx))
    return np.array(times), np.array(xs)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--samples", type=int, default=600)
    ap.add_argument("--lateral", action="store_true",
                    help="bank and sideslip in eqs. 12-15, as the monitor's default")
    args = ap.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    est = AirDataEstimator(AirDataEstimatorConfig(lateral_terms=args.lateral), variant="cmhe")
    probs, t_ours, x_ours = record_problems(args.samples, lateral=args.lateral)
    rows = [("CMHE RTI (numba) mhe_step", t_ours, None)]
    _, t_ref, x_ref = record_problems(args.samples, reference=True, lateral=args.lateral)
    rows.append(("CMHE RTI (numpy reference) mhe_step", t_ref, x_ref))
    for solver in ("ipopt", "sqpmethod+qrqp"):
        t, xs = run_casadi(est, probs, "ipopt" if solver == "ipopt" else "sqp")
        rows.append((f"CasADi {solver}", t[5:], xs))
    ours_med = float(np.median(t_ours))
    log.info(
        "| solver (N = 3, %d horizon problems) | median us | p99 us | t_CMHE / t (median) "
        "| 5.8 ms / median | max abs(x_hat_kk - CMHE) aoa deg, Vg, Wx, Wz m/s |",
        len(probs),
    )
    log.info("|---|---|---|---|---|---|")
    for name, t, xs in rows:
        med, p99 = np.median(t) * 1e6, np.percentile(t, 99) * 1e6
        dev = "-"
        if xs is not None:
            d = np.abs(xs[:, -1, :] - x_ours[:, -1, :]).max(axis=0)
            d[0] = np.degrees(d[0])
            dev = " ".join(f"{v:.3g}" for v in d)
        log.info(
            "| %s | %.1f | %.1f | %.3f | %.1f | %s |",
            name,
            med,
            p99,
            ours_med / np.median(t),
            PAPER_MS * 1e3 / med,
            dev,
        )
    xs_ip = rows[-2][2]
    d_all = np.abs(xs_ip[:, -1, :] - x_ours[:, -1, :])
    d_all[:, 0] = np.degrees(d_all[:, 0])
    for q in (50, 95, 100):
        log.info("|x_hat_k|k(IPOPT) - CMHE| p%d: aoa %.3g deg, Vg %.3g, Wx %.3g, Wz %.3g m/s", q,
                 *np.percentile(d_all, q, axis=0))
    t_ipopt = float(np.median(rows[-2][1]))
    t_sqp = float(np.median(rows[-1][1]))
    log.info(
        "targets: IPOPT / CMHE = %.1f (>= 10: %s); CMHE / sqpmethod = %.2f (<= 1: %s)",
        t_ipopt / ours_med,
        "met" if t_ipopt / ours_med >= 10.0 else "NOT met",
        ours_med / t_sqp,
        "met" if ours_med / t_sqp <= 1.0 else "NOT met",
    )


if __name__ == "__main__":
    main()
