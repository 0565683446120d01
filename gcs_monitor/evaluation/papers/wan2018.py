"""Wan2018 experiments: Figs. 3-5 (EKF / UMHE / CMHE), the sec. VI-B parametric campaign
(Tables III and IV) under several set-ups, and a diagnosis of its thresholds.

Every run goes through the real MAVLink path (:func:`gcs_monitor.evaluation.runs.run_one`:
``sim_vehicle.run.iter_run`` -> :class:`~gcs_monitor.monitor.Monitor`, the per-sample set
statuses captured with ``on_step``). Results: Markdown table returned, CSV + PNG written into
the experiment's out dir. Commands and measured tables: docs/results-airdata.md. The real-data
replay (OnSpeed) is :mod:`gcs_monitor.evaluation.papers.wan2018_real`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from gcs_monitor.config import MonitorConfig
from gcs_monitor.core.units import DEG2RAD, KT2MPS
from gcs_monitor.evaluation.configs import (
    airdata_of,
    declared_weather,
    open_loop,
    variant_config,
    weather_of,
    with_thresholds,
    with_weather,
    without_wind_accel,
)
from gcs_monitor.evaluation.records import METHOD_MEDIAN, METHOD_MONITOR, RunRecord
from gcs_monitor.evaluation.report import (
    fmt_fixed,
    md_table,
    pyplot,
    write_csv,
    write_metrics_csv,
)
from gcs_monitor.evaluation.runner import run_parallel
from gcs_monitor.evaluation.runs import run_one
from gcs_monitor.evaluation.scenarios import (
    CALIBRATION_SEED,
    CAMPAIGN_SEED,
    FIG45_T0_S,
    FULL_DURATION_S,
    NRZ_LITERAL_GAIN,
    SCHEDULE_CALM_RUNS,
    calm_calibration_scenarios,
    campaign_scenarios,
    fig_scenario,
    runaway_faults,
    wind_scenarios,
)
from gcs_monitor.evaluation.scoring import CALIBRATE_K, estimate_error, table3
from gcs_monitor.fdi.config import scheduled_threshold
from gcs_monitor.fdi.metrics import MetricsRow, metrics_table
from sim_vehicle.scenario import Scenario

VARIANTS = ("ekf", "umhe", "cmhe")
WINDOW_S = 17.76  # Wan2018 Fig. 5: 370 samples after the fault injection
FIG45_RATES_KTSPS = (5.0, 10.0, 15.0, 20.0, 25.0, 30.0)
# Wan2018 Table IV (CMHE-FTE) and Table III, for the side-by-side report
PAPER_T4 = {"aoa": (0.0, 0.0, 0.92, 19.16, 0.75), "cas": (0.0, 0.0, 0.0, 4.64, 0.80)}
PAPER_T3 = {"fault-free": (2.44, 8.22, 0.02, 0.02), "faulty": (16.39, 8.22, 0.24, 0.02)}


# ------------------------------------------------------------------------------------------------
# workers (module level: the runner's workers receive them by reference)
# ------------------------------------------------------------------------------------------------


def _series_run(job: tuple[Scenario, MonitorConfig, bool]) -> RunRecord:
    """One run with series; ``declare`` False keeps ``cfg``'s ``[airdata.weather]`` instead of
    the scenario's declared weather."""
    sc, cfg, declare = job
    return run_one(0, sc, cfg, keep_series=True, declare_weather=declare)


def _campaign_run(job: tuple[int, Scenario, MonitorConfig]
                  ) -> tuple[RunRecord, dict[str, tuple[float, float]]]:
    """One campaign run, its MHE estimation error (Table III) and the record without the
    series and events (small to send back)."""
    i, sc, cfg = job
    rec = run_one(i, sc, cfg, keep_series=True)
    stats = estimate_error(rec)
    rec.series = None
    rec.events = []
    return rec, stats


def _calibration_diag_run(job: tuple[int, Scenario, MonitorConfig, bool]) -> dict[str, Any]:
    i, sc, cfg, declare = job
    rec = run_one(i, sc, cfg, keep_series=False, declare_weather=declare)
    return {"i": i, "manoeuvre": sc.manoeuvre.kind, "wind": sc.wind.kind,
            "sigma_mps": sc.wind.turbulence_sigma_mps,
            "j_aoa": rec.j_max.get("aoa", math.nan), "j_cas": rec.j_max.get("cas", math.nan),
            "alarms": rec.raised.get(METHOD_MONITOR, 0)}


# ------------------------------------------------------------------------------------------------
# Figs. 4-5: three simultaneous CAS runaways
# ------------------------------------------------------------------------------------------------


def fig45_rows(rates: Sequence[float], jobs: int, *, wind: str = "1",
               variants: Sequence[str] = VARIANTS, progress: bool = True) -> list[dict[str, Any]]:
    """Per (variant, rate): detection of the three runaways, delays, mean J over 17.76 s."""
    w = wind_scenarios()[wind]
    dur = FIG45_T0_S + WINDOW_S + 2.0
    # the paper's bounds: the declared weather alone (no estimate of it from the flight)
    work = [(fig_scenario(f"fig45_{v}_{r:g}", w, dur, runaway_faults(r)),
             variant_config(v, weather_estimate=False), True)
            for v in variants for r in rates]
    rate_of = [r for _ in variants for r in rates]
    recs = run_parallel(_series_run, work, jobs, desc="fig45", progress=progress)
    rows = []
    for (_sc, cfg, _), rec, rate in zip(work, recs, rate_of, strict=True):
        s = rec.series or {}
        t = s["t_us"] * 1e-6
        inside = (t >= FIG45_T0_S) & (t < FIG45_T0_S + WINDOW_S)
        j = s["cas.rms"][inside]
        res = [f for f in rec.fault_results if f.method == METHOD_MONITOR]
        n_det = sum(f.detected for f in res)
        rows.append({"variant": airdata_of(cfg).estimator, "wind": wind,
                     "rate_ktsps": rate,
                     "detected_of_3": n_det,
                     "delay_max_s": max((f.delay_s for f in res if f.detected), default=math.nan),
                     "delay_min_s": min((f.delay_s for f in res if f.detected), default=math.nan),
                     "mean_rms_kts": float(np.nanmean(j)) / KT2MPS,
                     "threshold_kts": airdata_of(cfg).fdi.cas.threshold / KT2MPS})
    return rows


def wan2018_fig45(out_dir: Path, jobs: int = 1, quick: bool = False) -> str:
    """Three simultaneous CAS runaways in wind scenario 1 (Wan2018 Figs. 4-5)."""
    out = Path(out_dir)
    rates = (5.0, 15.0, 30.0) if quick else FIG45_RATES_KTSPS
    rows = fig45_rows(rates, jobs)
    hdr = list(rows[0])
    write_csv(out / "wan2018_fig45.csv", hdr, [[r[k] for k in hdr] for r in rows])
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6, 4))
    for v in VARIANTS:
        rr = [r for r in rows if r["variant"] == v]
        ax.plot([r["rate_ktsps"] for r in rr], [r["mean_rms_kts"] for r in rr], "o-",
                label=v.upper())
    ax.axhline(rows[0]["threshold_kts"], color="k", ls="--", lw=0.8, label="J_th")
    ax.set_xlabel("runaway rate [kts/s] (negative ramps)")
    ax.set_ylabel(f"mean CAS residual RMS over {WINDOW_S} s [kts]")
    ax.set_title("Wan2018 Fig. 5: three simultaneous CAS runaways, wind 1")
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(out / "wan2018_fig45.png", dpi=120)
    plt.close(fig)
    return md_table(["estimator", "rate [kts/s]", "detected of 3", "delay first [s]",
                     "delay all [s]", f"mean J over {WINDOW_S} s [kts]"],
                    [[r["variant"].upper(), f"{r['rate_ktsps']:g}", r["detected_of_3"],
                      fmt_fixed(r["delay_min_s"]), fmt_fixed(r["delay_max_s"]),
                      fmt_fixed(r["mean_rms_kts"])] for r in rows])


# ------------------------------------------------------------------------------------------------
# Fig. 3: fault-free robustness to wind
# ------------------------------------------------------------------------------------------------


WEATHER_ESTIMATED = "cmhe, weather estimated"  # fig3's row of the monitor's default CMHE


def wan2018_fig3(out_dir: Path, jobs: int = 1, quick: bool = False) -> str:
    """Maximum fault-free residual RMS (AoA, CAS) per wind scenario and estimator (Fig. 3)."""
    out = Path(out_dir)
    dur = 40.0 if quick else 120.0
    winds = wind_scenarios()
    # Wan2018 sec. VI-A: one set of assumed bounds for all three scenarios, which winds 1 and 2
    # respect and wind 3 exceeds. Ours: the declared weather of wind scenario 2 (its forecast,
    # configs.declared_weather), kept for all three runs, with the lateral terms of the
    # monitor's defaults (as measured so far: the weather used to replace the whole [airdata]
    # section, model switches included, whose default has them on). The monitor's weather
    # estimate is off: with it the CMHE learns wind 3 and its bounds follow (CMHE = UMHE in all
    # three winds), which is not what the figure compares.
    # Open loop (no isolation): Fig. 3 measures the residual generator's robustness; with the
    # default J_th in place a false alarm would remove the CAS set and the "fault-free J" after
    # it would be the model-only drift (see calibrate_campaign). The last column says whether
    # the default J_th (MonitorConfig: 1 deg, 4 kt) would have been crossed.
    assumed = declared_weather(fig_scenario("fig3_assumed", winds["2"], dur))
    # and the CMHE with the monitor's estimate of the weather (the declared one as its prior)
    setups = [(v, v, False) for v in VARIANTS] + [(WEATHER_ESTIMATED, "cmhe", True)]
    work = [(fig_scenario(f"fig3_{v}_w{k}", w, dur),
             with_weather(open_loop(variant_config(v, lateral=True, weather_estimate=est)),
                          assumed), False)
            for k, w in winds.items() for _, v, est in setups]
    labels = [label for _ in winds for label, _, _ in setups]
    default_th = airdata_of(MonitorConfig()).fdi
    recs = run_parallel(_series_run, work, jobs, desc="fig3")
    rows: list[list[Any]] = []
    for (sc, _cfg, _), rec, label in zip(work, recs, labels, strict=True):
        s = rec.series or {}
        t = s["t_us"] * 1e-6
        settled = t >= 5.0  # after the MHE's start-up transient
        ja, jc = float(np.nanmax(s["aoa.rms"][settled])), float(np.nanmax(s["cas.rms"][settled]))
        over = [g for g, j, th in (("AoA", ja, default_th.aoa.threshold),
                                   ("CAS", jc, default_th.cas.threshold)) if j > th]
        rows.append([label, sc.name.split("_w")[-1], ja / DEG2RAD,
                     jc / KT2MPS, "+".join(over) or "none"])
    write_csv(out / "wan2018_fig3.csv", ["variant", "wind", "max_J_aoa_deg", "max_J_cas_kts",
                                         "over_default_J_th"], rows)
    plt = pyplot()
    fig, axs = plt.subplots(1, 2, figsize=(9, 3.5))
    xs = np.arange(len(winds))
    for j, v in enumerate(VARIANTS):
        rr = [r for r in rows if r[0] == v]
        for a, col in zip(axs, (2, 3), strict=True):
            a.bar(xs + (j - 1) * 0.27, [r[col] for r in rr], 0.27, label=v.upper())
    for a, lab in zip(axs, ("max J AoA [deg]", "max J CAS [kts]"), strict=True):
        a.set_xticks(xs, [f"wind {k}" for k in winds])
        a.set_ylabel(lab)
        a.grid(alpha=0.3, axis="y")
    axs[0].legend()
    fig.suptitle("Wan2018 Fig. 3: fault-free maximum residual RMS")
    fig.tight_layout()
    fig.savefig(out / "wan2018_fig3.png", dpi=120)
    plt.close(fig)
    return md_table(["estimator", "wind", "max J AoA [deg]", "max J CAS [kts]",
                     "over default J_th (1 deg, 4 kt)"],
                    [[r[0].upper(), r[1], fmt_fixed(r[2], 3), fmt_fixed(r[3], 3), r[4]]
                     for r in rows])


# ------------------------------------------------------------------------------------------------
# Sec. VI-B parametric campaign: Tables III and IV
# ------------------------------------------------------------------------------------------------


def threshold_schedule(points: Sequence[tuple[float, float]], k: float = CALIBRATE_K,
                       min_runs: int = 5) -> tuple[float, float]:
    """J_th as a line in the declared turbulence, ``J_th(sigma) = k (J_0 + s sigma)``, from
    (declared Dryden sigma, worst fault-free J) of each calibration run (SI).

    Wan2018 sec. VI-B takes one J_th from the worst fault-free run of the whole campaign; the
    fault-free residual floor, though, is set by the gusts the one-step prediction cannot foresee
    (sigma_w / V per sample for AoA, sigma_u for CAS) and so grows with the turbulence the flight
    declares. ``J_0`` is the worst J of the runs declaring none, ``s`` the smallest slope that
    keeps every turbulent run under the line: the paper's rule "the worst fault-free J", applied
    at every turbulence level. With fewer than ``min_runs`` calm or turbulent calibration runs
    the line is not trusted: one fixed J_th (slope 0) as the paper. Returns (J_th at sigma = 0,
    slope), SI and SI per m/s."""
    calm = [j for sig, j in points if sig <= 0.0]
    if len(calm) < min_runs or len(points) - len(calm) < min_runs:
        return k * max((j for _, j in points), default=0.0), 0.0
    j0 = max(calm)
    slope = max((max(j - j0, 0.0) / sig for sig, j in points if sig > 0.0), default=0.0)
    return k * j0, k * slope


def calibrate_campaign(n_runs: int, jobs: int, duration_s: tuple[float, float],
                       base: MonitorConfig, *, seed: int = CALIBRATION_SEED,
                       progress: bool = True, schedule: bool = False,
                       n_calm: int = SCHEDULE_CALM_RUNS
                       ) -> tuple[dict[str, float], dict[str, float]]:
    """J_th per set from fault-free runs (Wan2018 sec. VI-B: the worst fault-free residual RMS
    so that the fault-free runs raise no alarm): ``1.5 x max J`` over ``n_runs`` fault-free runs
    of the calibration seed, or with ``schedule`` a line in the declared turbulence
    (:func:`threshold_schedule`), whose calm end also gets the non-turbulent runs of
    :func:`calm_calibration_scenarios` (``n_calm`` draws): the calm floor of the first schedule,
    set by 16 calm runs, was crossed by two calm s-turns of the campaign.
    The calibration runs are open loop (:func:`open_loop`): no instance is isolated, so the J
    measured is the residual generator's own fault-free level. (Calibrating with the default
    thresholds in place let false isolations in the calibration runs remove a whole set from
    the MHE -- Table I configuration II/III -- after which the model-only prediction drifts:
    that, not the residual generator, produced the 7.9 deg / 54 kt "worst fault-free J" of
    the first campaign.)

    Returns (thresholds, worst fault-free J), SI: ``thresholds[set]`` is J_th at zero declared
    turbulence, ``thresholds[set + "_per_turbulence"]`` its growth per m/s of Dryden sigma."""
    scs = campaign_scenarios(n_runs, seed, duration_s, fault_free_only=True)
    n_main = len(scs)
    if schedule and n_calm:
        scs += calm_calibration_scenarios(n_calm)
    work = [(i, sc, open_loop(base)) for i, sc in enumerate(scs)]
    res = run_parallel(_campaign_run, work, jobs, desc="calibrate", progress=progress)
    sig = [declared_weather(sc, weather_of(base)).turbulence_sigma_mps for sc in scs]
    th: dict[str, float] = {}
    for s in ("aoa", "cas"):
        pts = [(x, r.j_max.get(s, 0.0)) for x, (r, _) in zip(sig, res, strict=True)]
        th[s], th[f"{s}_per_turbulence"] = (
            threshold_schedule(pts) if schedule
            else (CALIBRATE_K * max((j for _, j in pts), default=0.0), 0.0))
    jmax = {s: max(r.j_max.get(s, 0.0) for r, _ in res) for s in ("aoa", "cas")}
    jmax["turbulence_max"] = max(sig, default=0.0)
    jmax["calm_runs_extra"] = float(len(scs) - n_main)
    return th, jmax


def run_campaign_wan2018(n_runs: int, n_cal: int, jobs: int, duration_s: tuple[float, float],
                         *, variant: str = "cmhe", seed: int = CAMPAIGN_SEED,
                         progress: bool = True, schedule: bool = False,
                         n_calm: int = SCHEDULE_CALM_RUNS, lateral: bool = False,
                         nrz_gain: float | None = None, restart_peers: bool = False,
                         equal_pair: bool = False) -> dict[str, Any]:
    """Calibrate J_th on fault-free seeds (one J_th per set, or scheduled on the declared
    turbulence), then run the campaign (monitor + median vote). ``lateral`` adds bank and
    sideslip to the model (``[airdata.filter] lateral_terms``; ours); ``nrz_gain`` reads
    Table II's non-return to zero literally (:func:`campaign_scenarios`; calibration is
    fault-free, so the thresholds do not change); ``restart_peers`` restarts the peers'
    windows on an isolation (``[airdata.fdi.*] restart_peers``; ours; calibration is open
    loop, so it does not change the thresholds either); ``equal_pair`` fuses the last two
    instances with equal weights (``[airdata.fdi.*] equal_pair_weights``; ours; calibration
    runs keep all three)."""
    t0 = time.perf_counter()
    base = variant_config(variant, lateral=lateral, restart_peers=restart_peers,
                          equal_pair=equal_pair)
    th, jmax = calibrate_campaign(n_cal, jobs, duration_s, base, progress=progress,
                                  schedule=schedule, n_calm=n_calm)
    cfg = with_thresholds(base, th["aoa"], th["cas"], th["aoa_per_turbulence"],
                          th["cas_per_turbulence"])
    scs = campaign_scenarios(n_runs, seed, duration_s, nrz_gain=nrz_gain)
    res = run_parallel(_campaign_run, [(i, sc, cfg) for i, sc in enumerate(scs)], jobs,
                       desc="campaign", progress=progress)
    recs = [r for r, _ in res]
    tables = {m: metrics_table([r.outcomes[m] for r in recs]) for m in (METHOD_MONITOR,
                                                                        METHOD_MEDIAN)}
    t3 = table3([(r.faulty, s) for r, s in res])
    cats: dict[str, int] = {}
    for sc in scs:
        c = sc.description.split("category ")[1].split(",")[0]
        cats[c] = cats.get(c, 0) + 1
    return {"tables": tables, "table3": t3, "thresholds": th, "jmax_cal": jmax, "records": recs,
            "lateral": lateral, "nrz_gain": nrz_gain, "restart_peers": restart_peers,
            "equal_pair": equal_pair,
            "err_stats": [st for _, st in res],
            "categories": cats, "sim_s": sum(sc.duration_s for sc in scs), "scenarios": scs,
            "wall_s": time.perf_counter() - t0, "variant": variant, "cfg": cfg}


def _row(rows: Sequence[MetricsRow], g: str) -> MetricsRow:
    return next(r for r in rows if r.group == g)


def campaign_markdown(res: dict[str, Any], n_runs: int, n_cal: int,
                      duration_s: tuple[float, float]) -> str:
    th = res["thresholds"]
    sig_max = res["jmax_cal"].get("turbulence_max", 0.0)
    jth_max = {g: th[g] + th.get(f"{g}_per_turbulence", 0.0) * sig_max for g in ("aoa", "cas")}
    scheduled = any(th.get(f"{g}_per_turbulence", 0.0) > 0.0 for g in ("aoa", "cas"))
    cats = res["categories"]
    lines = [
        f"Runs: {n_runs} (seed {CAMPAIGN_SEED}; categories "
        + ", ".join(f"{k}: {v}" for k, v in sorted(cats.items())) + f"), durations "
        f"{duration_s[0]:g}-{duration_s[1]:g} s, {res['sim_s']:.0f} simulated s in "
        f"{res['wall_s']:.0f} s wall. Estimator: {res['variant'].upper()}"
        + (" with bank and sideslip in eqs. 12-15 (`lateral_terms`)." if res.get("lateral")
           else " (Wan2018's wings-level model).")
        + (" Non-return to zero: the output falls to 10 % of the value (y = 0.1 x)."
           if res.get("nrz_gain") is None else
           f" Non-return to zero read literally: f = {res['nrz_gain']:g} x (the output "
           f"{100.0 * (1.0 + res['nrz_gain']):.0f} % of the value), not y = 0.1 x.")
        + (" The healthy peers' windows restart when an instance is isolated "
           "(`restart_peers`)." if res.get("restart_peers") else "")
        + (" The last two healthy instances of a set are fused with equal weights "
           "(`equal_pair_weights`)." if res.get("equal_pair") else ""),
        (f"Thresholds from {n_cal} fault-free runs of seed {CALIBRATION_SEED} and "
         f"{res['jmax_cal'].get('calm_runs_extra', 0.0):.0f} non-turbulent ones of seed "
         f"{CALIBRATION_SEED + 1} (60-200 s), run open loop (no "
         f"isolation), each with its declared weather, scheduled on the declared turbulence "
         f"sigma (1.5 x the worst fault-free J at each level, `threshold_schedule`): J_th AoA = "
         f"{th['aoa'] / DEG2RAD:.3f} deg + {th['aoa_per_turbulence'] / DEG2RAD:.3f} deg per "
         f"m/s of sigma ({jth_max['aoa'] / DEG2RAD:.3f} deg at the largest declared sigma, "
         f"{sig_max:.2f} m/s; worst J {res['jmax_cal']['aoa'] / DEG2RAD:.3f}), CAS = "
         f"{th['cas'] / KT2MPS:.2f} kt + {th['cas_per_turbulence'] / KT2MPS:.2f} kt per m/s "
         f"({jth_max['cas'] / KT2MPS:.2f} kt; worst J {res['jmax_cal']['cas'] / KT2MPS:.2f}); "
         f"Wan2018: 2.9 deg, 12 kts.") if scheduled else
        (f"Thresholds from {n_cal} fault-free runs of seed {CALIBRATION_SEED}, run open loop (no "
         f"isolation), each with its declared weather (1.5 x worst fault-free J): J_th AoA = "
         f"{th['aoa'] / DEG2RAD:.3f} deg (worst J "
         f"{res['jmax_cal']['aoa'] / DEG2RAD:.3f}), CAS = {th['cas'] / KT2MPS:.2f} kt (worst J "
         f"{res['jmax_cal']['cas'] / KT2MPS:.2f}); Wan2018: 2.9 deg, 12 kts."),
        "",
        "Table IV (FDI):",
        "",
    ]
    rows: list[list[Any]] = []
    for g in ("aoa", "cas"):
        p = PAPER_T4[g]
        rows.append([f"Wan2018 {g.upper()}", "-", "-", *[fmt_fixed(x) for x in p]])
        for m, lab in ((METHOD_MONITOR, f"ours {res['variant'].upper()}"),
                       (METHOD_MEDIAN, "median vote (same runs)")):
            r = _row(res["tables"][m], g)
            rows.append([f"{lab} {g.upper()}", r.n_fault_free, r.n_faulty,
                         fmt_fixed(r.far_pct), fmt_fixed(r.mdr_pct), fmt_fixed(r.fir_pct),
                         fmt_fixed(r.delay_max_s), fmt_fixed(r.delay_mean_s)])
    lines.append(md_table(["", "fault-free runs", "faulty runs", "FAR [%]", "MDR [%]", "FIR [%]",
                           "DetD max [s]", "DetD mean [s]"], rows))
    lines += ["", "Table III (estimation error of the MHE output vs truth; CAS only while a CAS "
              "instance is healthy):", ""]
    t3 = res["table3"]
    rows3 = []
    for k in ("fault-free", "faulty"):
        rows3.append([f"Wan2018 {k}", *[fmt_fixed(x) for x in PAPER_T3[k]]])
        rows3.append([f"ours {k}", *[fmt_fixed(x, 3) for x in t3[k]]])
    lines.append(md_table(["", "max AoA [deg]", "max CAS [kts]", "mean AoA [deg]",
                           "mean CAS [kts]"], rows3))
    lines += ["", "Per fault family (Table II), monitor: faults detected / injected, mean and max "
              "delay:", ""]
    lines.append(md_table(["family", "AoA detected", "AoA delay mean / max [s]", "CAS detected",
                           "CAS delay mean / max [s]"], per_family_rows(res["records"])))
    lines += ["", "By fault size against J_th (bias: |b|, oscillation: amplitude / sqrt 2, noise: "
              "sigma; the other families have no size parameter), monitor: detected / injected, "
              "mean and max delay:", ""]
    lines.append(md_table(["fault size", "AoA detected", "AoA delay mean / max [s]",
                           "CAS detected", "CAS delay mean / max [s]"],
                          per_size_rows(fault_rows(res), th)))
    return "\n".join(lines)


def per_family_rows(recs: Sequence[RunRecord]) -> list[list[str]]:
    """Detection per Table II family and set (monitor), for the campaign report."""
    rows = []
    fams = sorted({f.kind for r in recs for f in r.fault_results})
    for fam in fams:
        row = [fam]
        for g in ("aoa", "cas"):
            fr = [f for r in recs for f in r.fault_results
                  if f.method == METHOD_MONITOR and f.kind == fam and f.channel.startswith(g)]
            d = [f.delay_s for f in fr if f.detected]
            row += [f"{len(d)} / {len(fr)}",
                    f"{fmt_fixed(float(np.mean(d)))} / {fmt_fixed(max(d))}" if d else "-"]
        rows.append(row)
    return rows


FAULT_ROW_HEAD = ["run", "name", "manoeuvre", "wind", "channel", "kind", "t_start_s", "params_si",
                  "j_th_si", "monitor_detected", "monitor_delay_s", "median_detected",
                  "median_delay_s"]


def fault_rows(res: dict[str, Any]) -> list[list[Any]]:
    """Every injected fault of a campaign (``FAULT_ROW_HEAD``): its Table II parameters (SI)
    and, per method, whether and how soon it was detected."""
    recs: list[RunRecord] = res["records"]
    cfg: MonitorConfig | None = res.get("cfg")
    out = []
    for r, sc in zip(recs, res.get("scenarios", [None] * len(recs)), strict=True):
        spec = {f.channel: f for f in sc.faults} if sc is not None else {}
        jth: dict[str, Any] = {"aoa": "", "cas": ""}
        if cfg is not None and sc is not None:
            sig = declared_weather(sc, weather_of(cfg)).turbulence_sigma_mps
            fdi = airdata_of(cfg).fdi
            jth = {"aoa": scheduled_threshold(fdi.aoa, sig),
                   "cas": scheduled_threshold(fdi.cas, sig)}
        by = {(f.method, f.channel): f for f in r.fault_results}
        for ft in r.faults:
            ch = str(ft.channel)
            fs = spec.get(ch)
            params = ";".join(f"{k}={v:.6g}" if isinstance(v, float) else f"{k}={v}"
                              for k, v in (fs.params if fs is not None else ()))
            row: list[Any] = [r.index, r.name, r.manoeuvre, r.wind, ch, ft.kind,
                              ft.t_start_us * 1e-6, params, jth[ft.channel.kind]]
            for m in (METHOD_MONITOR, METHOD_MEDIAN):
                fr = by.get((m, ch))
                row += [int(fr.detected), fr.delay_s] if fr is not None else ["", ""]
            out.append(row)
    return out


def fault_size(kind: str, params_si: str) -> float | None:
    """The size of a Table II fault, SI, comparable with J (an RMS): |bias|, oscillation
    amplitude / sqrt(2), noise sigma; None for faults whose size is not a parameter (jam,
    runaway, non-return to zero: they grow with time or follow the flight condition)."""
    p = dict(kv.split("=", 1) for kv in params_si.split(";")) if params_si else {}
    stem = {"bias": "bias", "oscillation": "amplitude", "noise": "sigma"}.get(kind)
    if stem is None:
        return None
    v = next((float(x) for k, x in p.items() if k.startswith(stem)), None)
    if v is None:
        return None
    return abs(v) / math.sqrt(2.0) if kind == "oscillation" else abs(v)


def per_size_rows(rows: Sequence[Sequence[Any]], thresholds: dict[str, float]) -> list[list[str]]:
    """Monitor detection by fault size against the run's J_th (column ``j_th_si``, else
    ``thresholds[set]``) for bias, oscillation and noise, and for the families without a size
    parameter."""
    head = FAULT_ROW_HEAD
    bins: dict[tuple[str, str], list[float | None]] = {}
    order = ["size >= 2 J_th", "J_th <= size < 2 J_th", "size < J_th", "jam", "runaway", "nrz"]
    for row in rows:
        d = dict(zip(head, row, strict=True))
        g = "aoa" if str(d["channel"]).startswith("aoa") else "cas"
        size = fault_size(str(d["kind"]), str(d["params_si"]))
        if size is None:
            key = str(d["kind"])
        else:
            jt = d.get("j_th_si", "")
            q = size / (float(jt) if jt not in ("", None) else thresholds[g])
            key = order[0] if q >= 2.0 else order[1] if q >= 1.0 else order[2]
        det = str(d["monitor_detected"]) == "1"
        bins.setdefault((g, key), []).append(float(d["monitor_delay_s"]) if det else None)
    out = []
    for key in order:
        row_ = [key]
        for g in ("aoa", "cas"):
            v = bins.get((g, key), [])
            dl = [x for x in v if x is not None]
            row_ += [f"{len(dl)} / {len(v)}" if v else "-",
                     f"{fmt_fixed(float(np.mean(dl)))} / {fmt_fixed(max(dl))}" if dl else "-"]
        out.append(row_)
    return out


def _campaign_files(res: dict[str, Any], out: Path) -> None:
    recs: list[RunRecord] = res["records"]
    errs = res.get("err_stats", [{}] * len(recs))
    rows = []
    for r, st in zip(recs, errs, strict=True):
        for m in (METHOD_MONITOR, METHOD_MEDIAN):
            for g, o in r.outcomes[m].items():
                # Table III per run (MHE output vs truth, SI): monitor rows only
                e = st.get(g) if m == METHOD_MONITOR else None
                rows.append([r.index, r.name, r.duration_s, r.manoeuvre, r.wind,
                             ";".join(f"{f.channel}:{f.kind}" for f in r.faults), m, g,
                             int(o.false_alarm), int(o.missed), int(o.false_isolation),
                             o.delay_s, "" if e is None else e[0], "" if e is None else e[1]])
    write_csv(out / "wan2018_campaign_runs.csv",
              ["run", "name", "duration_s", "manoeuvre", "wind", "faults", "method", "group",
               "false_alarm", "missed", "false_isolation", "delay_s", "est_err_max_si",
               "est_err_mean_si"],
         rows)
    frows = fault_rows(res)
    write_csv(out / "wan2018_campaign_faults.csv", FAULT_ROW_HEAD, frows)
    write_metrics_csv(out / "wan2018_campaign_metrics.csv", res["tables"])
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6, 4))
    for g in ("aoa", "cas"):
        d = [f.delay_s for r in recs for f in r.fault_results
             if f.method == METHOD_MONITOR and f.channel.startswith(g) and f.detected]
        if d:
            ax.hist(d, bins=30, alpha=0.6, label=f"{g.upper()} ({len(d)} faults)")
    ax.set_xlabel("detection delay [s]")
    ax.set_ylabel("faults")
    ax.set_title(f"Wan2018 campaign, {res['variant'].upper()}")
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "wan2018_campaign_delays.png", dpi=120)
    plt.close(fig)


def wan2018_calibration(out_dir: Path, jobs: int = 1, quick: bool = False) -> str:
    """Diagnosis of the campaign thresholds: the worst fault-free J of the calibration runs
    (seed 1000) under four set-ups: closed loop with the default J_th (1 deg, 4 kt) and the
    default fixed wind box (what the first campaign calibrated with), open loop with the fixed
    box, open loop with each run's declared weather on the eq. 13 model, and the same with
    eq. 8's wind-acceleration term (what :func:`calibrate_campaign` does)."""
    out = Path(out_dir)
    n, dur = (6, (40.0, 60.0)) if quick else (40, FULL_DURATION_S)
    scs = campaign_scenarios(n, CALIBRATION_SEED, dur, fault_free_only=True)
    base = variant_config("cmhe")
    eq13 = without_wind_accel(base)
    setups = (("closed loop, default J_th, fixed box", base, False),
              ("open loop, fixed box", open_loop(base), False),
              ("open loop, declared weather, eq. 13 (no eq. 8 term)", open_loop(eq13), True),
              ("open loop, declared weather", open_loop(base), True))
    rows, csv_rows = [], []
    for name, cfg, declare in setups:
        res = run_parallel(_calibration_diag_run,
                           [(i, sc, cfg, declare) for i, sc in enumerate(scs)], jobs,
                           desc=name[:20], progress=not quick)
        wa = max(res, key=lambda r: r["j_aoa"])
        wc = max(res, key=lambda r: r["j_cas"])
        rows.append([name, fmt_fixed(wa["j_aoa"] / DEG2RAD, 3),
                     f"{wa['i']} ({wa['manoeuvre']}, {wa['wind']}, σ {wa['sigma_mps']:g} m/s)",
                     fmt_fixed(wc["j_cas"] / KT2MPS, 2),
                     f"{wc['i']} ({wc['manoeuvre']}, {wc['wind']}, σ {wc['sigma_mps']:g} m/s)",
                     sum(1 for r in res if r["alarms"])])
        csv_rows += [[name, r["i"], r["manoeuvre"], r["wind"], r["sigma_mps"],
                      r["j_aoa"] / DEG2RAD, r["j_cas"] / KT2MPS, r["alarms"]] for r in res]
    write_csv(out / "wan2018_calibration.csv", ["setup", "run", "manoeuvre", "wind", "sigma_mps",
                                                "max_J_aoa_deg", "max_J_cas_kts", "alarms"],
              csv_rows)
    return (f"{n} fault-free calibration runs (seed {CALIBRATION_SEED}), durations "
            f"{dur[0]:g}-{dur[1]:g} s.\n\n"
            + md_table(["set-up", "worst J AoA [deg]", "run", "worst J CAS [kt]", "run",
                        "runs with alarms"], rows))


def wan2018_campaign(out_dir: Path, jobs: int = 1, quick: bool = False,
                     schedule: bool = False, lateral: bool = False,
                     nrz_gain: float | None = None, restart_peers: bool = False,
                     equal_pair: bool = False) -> str:
    """Wan2018 sec. VI-B: 249 runs (140 fault-free), Tables III and IV, median-vote baseline."""
    out = Path(out_dir)
    if quick:
        n, n_cal, dur = 12, 4, (40.0, 60.0)
    else:
        n, n_cal, dur = 249, 40, FULL_DURATION_S
    res = run_campaign_wan2018(n, n_cal, jobs, dur, schedule=schedule,
                               n_calm=12 if quick else SCHEDULE_CALM_RUNS, lateral=lateral,
                               nrz_gain=nrz_gain, restart_peers=restart_peers,
                               equal_pair=equal_pair)
    _campaign_files(res, out)
    md = campaign_markdown(res, n, n_cal, dur)
    (out / "wan2018_campaign.md").write_text(md + "\n")
    return md


# The campaign's set-ups besides Wan2018's scheme (``wan2018_campaign``): name suffix ->
# (summary, keyword arguments of :func:`wan2018_campaign`). Each runs on the same 249 runs with
# non-return to zero as the output falling to 10 %, and as ``<name>_literal_nrz`` with it read
# literally; the ``_LITERAL_ONLY`` ablations were measured with the literal reading only.
CAMPAIGN_SETUPS: dict[str, tuple[str, dict[str, bool]]] = {
    "restart": ("The monitor's defaults: the lateral terms, one J_th, and the peers' windows "
                "restarted when an instance is isolated (``[airdata.fdi.*] restart_peers``), on "
                "the same runs.", {"lateral": True, "restart_peers": True}),
    "extensions": ("All our extensions together (lateral terms, J_th scheduled on the declared "
                   "turbulence, the peers' windows restarted on an isolation, equal weights for "
                   "the last two instances; ``configs/wan2018_transport_extensions.toml``), on "
                   "the same runs.",
                   {"schedule": True, "lateral": True, "restart_peers": True,
                    "equal_pair": True}),
}
_LITERAL_ONLY: dict[str, tuple[str, dict[str, bool]]] = {
    "scheduled": ("J_th scheduled on the declared turbulence (:func:`threshold_schedule`), our "
                  "alternative to Wan2018's single J_th, on its own.", {"schedule": True}),
    "lateral": ("Bank and sideslip in the model (``[airdata.filter] lateral_terms``) and J_th "
                "scheduled on the declared turbulence.", {"schedule": True, "lateral": True}),
    "lateral_only": ("The lateral terms with Wan2018's single J_th and windows: the model "
                     "change on its own.", {"lateral": True}),
}


def _campaign_experiment(summary: str, **kw: Any) -> Callable[[Path, int, bool], str]:
    """A named experiment: :func:`wan2018_campaign` with the set-up ``kw``."""
    def run(out_dir: Path, jobs: int = 1, quick: bool = False) -> str:
        return wan2018_campaign(out_dir, jobs, quick, **kw)

    run.__doc__ = summary
    return run


def campaign_experiments() -> dict[str, Callable[[Path, int, bool], str]]:
    """Every campaign set-up under both readings of Table II's non-return to zero."""
    out = {f"wan2018_campaign_{k}": _campaign_experiment(doc, **kw)
           for k, (doc, kw) in CAMPAIGN_SETUPS.items()}
    literal = {"": ("Wan2018's scheme (as ``wan2018_campaign``).", {}), **CAMPAIGN_SETUPS,
               **_LITERAL_ONLY}
    for k, (doc, kw) in literal.items():
        out[f"wan2018_campaign{'_' + k if k else ''}_literal_nrz"] = _campaign_experiment(
            "Non-return to zero read literally (f = 0.1 x). " + doc,
            nrz_gain=NRZ_LITERAL_GAIN, **kw)
    return out


# ------------------------------------------------------------------------------------------------
# registry
# ------------------------------------------------------------------------------------------------


def experiments() -> dict[str, Callable[[Path, int, bool], str]]:
    """Named experiments for ``gcs-monitor evaluate --experiment NAME``."""
    out: dict[str, Callable[[Path, int, bool], str]] = {
        "wan2018_fig45": wan2018_fig45,
        "wan2018_fig3": wan2018_fig3,
        "wan2018_campaign": wan2018_campaign,
        "wan2018_calibration": wan2018_calibration,
        **campaign_experiments(),
    }
    return out

