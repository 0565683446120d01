"""Everything the evaluation writes: Markdown tables, CSV files and PNG plots.

The generic helpers (:func:`md_table`, :func:`write_csv`, :func:`pyplot`, the number formats)
are used by every experiment. The campaign report (:func:`write_report`) writes into a
campaign's ``out_dir``:

* ``report.md`` -- the Markdown returned as ``CampaignResult.markdown``;
* ``metrics.csv`` -- Wan2018 Table IV rows, one per (method, group);
* ``runs.csv`` -- one row per (run, method, group): scenario, faults, outcome, delay;
* ``faults.csv`` -- one row per (run, injected fault, method): detected, delay;
* ``example_series.csv`` -- per air sample of the example run (measured, reference, J, fused);
* ``detection_delay.png``, ``rates_per_channel.png``, ``residual_rms_example.png``.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from gcs_monitor.core.units import DEG2RAD, KT2MPS
from gcs_monitor.evaluation.configs import (
    airdata_of,
    detect_n,
    imu_of,
    sim_air_period_s,
    window_n,
)
from gcs_monitor.evaluation.records import (
    AXES,
    METHOD_MONITOR,
    REPORT_SCALE,
    UNITS,
    CampaignResult,
    ImuRun,
    RunRecord,
)
from gcs_monitor.fdi.metrics import MetricsRow

METHOD_LABEL = {"monitor": "monitor", "median_vote": "median vote (baseline)",
                "fixed_threshold": "fixed threshold (baseline)", "virtual": "MHE virtual sensor"}


# ------------------------------------------------------------------------------------------------
# generic helpers
# ------------------------------------------------------------------------------------------------


def fmt_fixed(x: float | None, nd: int = 2) -> str:
    """``x`` with ``nd`` decimals; ``-`` for None, NaN and infinities."""
    return "-" if x is None or not math.isfinite(x) else f"{x:.{nd}f}"


def fmt_sig(x: float, nd: int = 3) -> str:
    """``x`` with ``nd`` significant digits (exponent form from 1e4); ``-`` when not finite."""
    if not math.isfinite(x):
        return "-"
    return f"{x:.{nd}g}" if abs(x) < 1e4 else f"{x:.3e}"


def md_table(header: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    """A Markdown table; float cells with :func:`fmt_sig`, every other cell with ``str``."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(fmt_sig(c) if isinstance(c, float) else str(c) for c in r) + " |"
              for r in rows]
    return "\n".join(lines)


def write_csv(path: Path, header: Sequence[str], rows: Sequence[Sequence[Any]]) -> Path:
    """One CSV file (its folder created); returns ``path``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(rows)
    return path


def write_metrics_csv(path: Path, tables: dict[str, list[MetricsRow]]) -> Path:
    """Wan2018 Table IV rows, one per (method, group), as CSV."""
    return write_csv(path, ["method", "group", "n_fault_free", "n_faulty", "far_pct", "mdr_pct",
                            "fir_pct", "delay_max_s", "delay_mean_s"],
                     [[m, r.group, r.n_fault_free, r.n_faulty, r.far_pct, r.mdr_pct, r.fir_pct,
                       r.delay_max_s, r.delay_mean_s] for m, rows in tables.items() for r in rows])


def pyplot() -> Any:
    """``matplotlib.pyplot`` on the Agg backend (files only, no display)."""
    # imported here, not at the top: pyplot takes ~0.5 s to import and only plotting needs it
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_imu_run(run: ImuRun, names: Sequence[str], path: Path, title: str = "") -> None:
    """f_hat of each estimator against the true fault, six panels (acc m/s^2, gyro deg/s)."""
    plt = pyplot()
    fig, axs = plt.subplots(3, 2, figsize=(11, 8), sharex=True)
    units = ("m/s^2",) * 3 + ("deg/s",) * 3
    for i in range(6):
        ax = axs[i % 3, i // 3]
        ax.plot(run.t_s, run.f_true[:, i] * REPORT_SCALE[i], "k", lw=2, label="true")
        for n in names:
            if n in run.f_hat:
                ax.plot(run.t_s, run.f_hat[n][:, i] * REPORT_SCALE[i], lw=0.8, label=n)
        ax.set_ylabel(f"f_{AXES[i]} [{units[i]}]")
        ax.grid(True, alpha=0.3)
    axs[0, 0].legend(fontsize=7)
    axs[2, 0].set_xlabel("t [s]")
    axs[2, 1].set_xlabel("t [s]")
    fig.suptitle(title or run.name)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)


def _disp(group: str, si: float) -> float:
    return si / UNITS.get(group, ("", 1.0))[1]


# ------------------------------------------------------------------------------------------------
# campaign report (``gcs-monitor evaluate --preset-set``)
# ------------------------------------------------------------------------------------------------


def monitor_label(res: CampaignResult) -> str:
    air, fam = airdata_of(res.config), imu_of(res.config)
    ref = f"MHE reference ({air.estimator})" if air.estimator != "none" else "consensus only"
    imu = [n for n, on in (("imu_ts", fam.ts.enabled), ("imu_hosm", fam.hosm.enabled))
           if on and fam.enabled]
    return f"monitor, {ref}" + (f", IMU: {'+'.join(imu)}" if imu else "")


def metrics_markdown(res: CampaignResult) -> str:
    rows = []
    for m, mrows in res.tables.items():
        label = monitor_label(res) if m == METHOD_MONITOR else METHOD_LABEL[m]
        rows += [[label, r.group, r.n_fault_free, r.n_faulty, fmt_fixed(r.far_pct),
                  fmt_fixed(r.mdr_pct), fmt_fixed(r.fir_pct), fmt_fixed(r.delay_max_s),
                  fmt_fixed(r.delay_mean_s)] for r in mrows]
    return md_table(["method", "group", "fault-free runs", "faulty runs", "FAR [%]", "MDR [%]",
                     "FIR [%]", "DetD max [s]", "DetD mean [s]"], rows)


def per_kind_markdown(runs: Sequence[RunRecord]) -> str:
    """Detection rate and delay per injected fault kind and method."""
    acc: dict[tuple[str, str], list[tuple[bool, float]]] = {}
    for r in runs:
        for fr in r.fault_results:
            acc.setdefault((fr.kind, fr.method), []).append((fr.detected, fr.delay_s))
    methods = sorted({m for _, m in acc}, key=lambda m: list(METHOD_LABEL).index(m))
    rows = []
    for kind in sorted({k for k, _ in acc}):
        cells = []
        n = 0
        for m in methods:
            v = acc.get((kind, m), [])
            n = len(v)
            det = [d for ok, d in v if ok]
            mean = fmt_fixed(float(np.mean(det)) if det else math.nan)
            cells.append(f"{100.0 * len(det) / n:.0f} / {mean}" if n else "-")
        rows.append([kind, n, *cells])
    return md_table(["fault kind", "faults"] + [
        f"{METHOD_LABEL[m]}: detected [%] / mean delay [s]" for m in methods], rows)


def output_markdown(runs: Sequence[RunRecord]) -> str:
    """Reconstruction RMSE and output error vs truth (mean over runs)."""
    lines = []
    recon: dict[str, list[float]] = {}
    for r in runs:
        for ch, v in r.recon_rmse.items():
            if math.isfinite(v):
                recon.setdefault(ch.rstrip("0123456789"), []).append(v)
    if recon:
        lines += ["Fault reconstruction (monitor): RMS over the fault interval of "
                  "`(y_i - reference) - f_i`, f_i the applied fault (truth).", ""]
        rows = []
        for s, vals in sorted(recon.items()):
            u = UNITS[s][0]
            rows.append([s, len(vals), f"{fmt_fixed(_disp(s, float(np.mean(vals))), 3)} {u}",
                         f"{fmt_fixed(_disp(s, float(np.max(vals))), 3)} {u}"])
        lines += [md_table(["set", "faulty channels", "RMSE mean", "RMSE max"], rows), ""]
    out: dict[tuple[str, str], list[float]] = {}
    lost: dict[tuple[str, str], int] = {}
    for r in runs:
        for m, d in r.output_rmse.items():
            for s, v in d.items():
                if math.isfinite(v):
                    out.setdefault((m, s), []).append(v)
                lost[(m, s)] = lost.get((m, s), 0) + r.output_lost.get(m, {}).get(s, 0)
    if out:
        lines += ["Output handed downstream vs truth, RMS over all air-data samples (all runs): "
                  "adaptive weighted fusion (monitor), median selection (baselines), MHE "
                  "estimate (virtual sensor).", ""]
        rows = []
        for (m, s), errs in sorted(out.items(), key=lambda kv: (kv[0][1], kv[0][0])):
            u = UNITS[s][0]
            rows.append([METHOD_LABEL[m], s, len(errs),
                         f"{fmt_fixed(_disp(s, float(np.mean(errs))), 3)} {u}",
                         f"{fmt_fixed(_disp(s, float(np.max(errs))), 3)} {u}", lost[(m, s)]])
        lines.append(md_table(["output", "set", "runs", "RMSE mean", "RMSE max",
                               "samples without output"], rows))
    return "\n".join(lines)


def calibration_markdown(res: CampaignResult) -> str:
    """Fault-free residual statistics against the thresholds in use."""
    air, imu = airdata_of(res.config).fdi, imu_of(res.config).ts.fdi
    th = {"aoa": air.aoa.threshold, "cas": air.cas.threshold, "acc": imu.acc.threshold,
          "gyro": imu.gyro.threshold}
    free = [r for r in res.runs if not r.faulty]
    if not free:
        return "No fault-free run in this campaign."
    rows = []
    for g in ("aoa", "cas", "acc", "gyro"):
        js = [r.j_max[g] for r in free if g in r.j_max]
        if not js:
            continue
        u = UNITS[g][0]
        jm = max(js)
        cal = [r.j_calibrated[g] for r in free if g in r.j_calibrated]
        c = f"{_disp(g, max(cal)):.3g} {u}" if cal else "-"
        rows.append([g, f"{_disp(g, th[g]):.3g} {u}", f"{_disp(g, jm):.3g} {u}",
                     f"{th[g] / jm if jm > 0 else math.inf:.2f}", c])
    return md_table(["group", "J_th in use", "largest fault-free J", "margin J_th / J",
                     "calibrate() (rule max, k=1.5)"], rows)


def _write_campaign_csvs(res: CampaignResult) -> list[Path]:
    out = res.out_dir
    files = [write_metrics_csv(out / "metrics.csv", res.tables)]
    runs = []
    for r in res.runs:
        fs = ";".join(f"{f.channel}:{f.kind}@{f.t_start_us * 1e-6:g}" for f in r.faults)
        for m, d in r.outcomes.items():
            for g, o in d.items():
                runs.append([r.index, r.name, r.seed, r.duration_s, r.manoeuvre, r.wind, fs, m,
                             g, int(o.faulty_run), int(o.false_alarm), int(o.missed),
                             int(o.false_isolation), o.delay_s, r.raised.get(m, 0),
                             round(r.wall_s, 3)])
    files.append(write_csv(
        out / "runs.csv",
        ["run", "name", "seed", "duration_s", "manoeuvre", "wind", "faults", "method", "group",
         "faulty_run", "false_alarm", "missed", "false_isolation", "delay_s", "raised",
         "wall_s"], runs))
    faults = []
    for r in res.runs:
        starts = {str(f.channel): f.t_start_us * 1e-6 for f in r.faults}
        for fr in r.fault_results:
            faults.append([r.index, r.name, fr.channel, fr.kind, starts[fr.channel], fr.method,
                           int(fr.detected), fr.delay_s,
                           r.recon_rmse.get(fr.channel, math.nan)
                           if fr.method == METHOD_MONITOR else ""])
    files.append(write_csv(
        out / "faults.csv",
        ["run", "name", "channel", "kind", "t_start_s", "method", "detected", "delay_s",
         "recon_rmse_si"], faults))
    ex = next((r for r in res.runs if r.series is not None), None)
    if ex is not None and ex.series is not None:
        p = out / "example_series.csv"
        s = ex.series
        cols: list[tuple[str, np.ndarray]] = [("t_s", s["t_us"] * 1e-6)]
        for k in sorted(s):
            if k == "t_us":
                continue
            v = s[k] if s[k].ndim == 2 else s[k][:, None]
            for j in range(v.shape[1]):
                cols.append((k if v.shape[1] == 1 else f"{k}.{j}", v[:, j]))
        np.savetxt(p, np.column_stack([c for _, c in cols]), delimiter=",",
                   header=",".join(n for n, _ in cols), comments="", fmt="%.9g")
        files.append(p)
    return files


def _campaign_plots(res: CampaignResult) -> list[Path]:
    plt = pyplot()
    out = res.out_dir
    files = []
    methods = list(res.tables)
    # detection delay histogram per method
    fig, ax = plt.subplots(figsize=(7, 4))
    delays = {m: [fr.delay_s for r in res.runs for fr in r.fault_results
                  if fr.method == m and fr.detected] for m in methods}
    allv = [d for v in delays.values() for d in v]
    if allv:
        bins = np.linspace(0.0, max(max(allv), 1.0), 30).tolist()
        for m in methods:
            if delays[m]:
                ax.hist(delays[m], bins=bins, alpha=0.5, label=METHOD_LABEL[m])
        ax.legend()
    ax.set_xlabel("detection delay [s]")
    ax.set_ylabel("faults")
    ax.set_title(f"{res.preset_set}: detection delay per injected fault")
    fig.tight_layout()
    p = out / "detection_delay.png"
    fig.savefig(p, dpi=110)
    plt.close(fig)
    files.append(p)
    # FAR / MDR / FIR per channel kind and method
    groups = sorted({r.group for rows in res.tables.values() for r in rows
                     if r.group in ("aoa", "cas")})
    fig, axs = plt.subplots(1, 3, figsize=(11, 3.6), sharey=True)
    width = 0.8 / max(len(methods), 1)
    for ax, (attr, title) in zip(axs, (("far_pct", "false-alarm rate"),
                                       ("mdr_pct", "missed-detection rate"),
                                       ("fir_pct", "false-isolation rate")), strict=True):
        for k, m in enumerate(methods):
            rows = {r.group: r for r in res.tables[m]}
            vals = [getattr(rows[g], attr) if g in rows else math.nan for g in groups]
            ax.bar(np.arange(len(groups)) + k * width, np.nan_to_num(vals), width,
                   label=METHOD_LABEL[m])
        ax.set_xticks(np.arange(len(groups)) + width * (len(methods) - 1) / 2, groups)
        ax.set_title(title)
        ax.set_ylabel("%")
    axs[0].legend(fontsize=7)
    fig.tight_layout()
    p = out / "rates_per_channel.png"
    fig.savefig(p, dpi=110)
    plt.close(fig)
    files.append(p)
    ex = next((r for r in res.runs if r.series is not None), None)
    if ex is not None and ex.series is not None and "aoa.rms" in ex.series:
        s = ex.series
        t = s["t_us"] * 1e-6
        fig, axs = plt.subplots(2, 2, figsize=(11, 6), sharex=True)
        for col, g in enumerate(("aoa", "cas")):
            u, scale = UNITS[g]
            th = getattr(airdata_of(res.config).fdi, g).threshold
            ax = axs[0, col]
            for i in range(s[f"{g}.measured"].shape[1]):
                ax.plot(t, s[f"{g}.measured"][:, i] / scale, lw=0.7, label=f"{g}{i}")
            ax.plot(t, s[f"{g}.true"] / scale, "k--", lw=0.8, label="true")
            ax.set_ylabel(f"{g} [{u}]")
            ax.legend(fontsize=7)
            ax = axs[1, col]
            for i in range(s[f"{g}.rms"].shape[1]):
                ax.plot(t, s[f"{g}.rms"][:, i] / scale, lw=0.8, label=f"J {g}{i}")
            ax.axhline(th / scale, color="r", ls=":", label="J_th")
            for f in ex.faults:
                if f.channel.kind == g:
                    ax.axvline(f.t_start_us * 1e-6, color="gray", ls="--", lw=0.8)
            ax.set_ylabel(f"residual RMS J [{u}]")
            ax.set_xlabel("vehicle time [s]")
            ax.legend(fontsize=7)
        fs = ", ".join(f"{f.channel} {f.kind}" for f in ex.faults) or "fault-free"
        fig.suptitle(f"{ex.name}: {fs} ({monitor_label(res)})", fontsize=9)
        fig.tight_layout()
        p = out / "residual_rms_example.png"
        fig.savefig(p, dpi=110)
        plt.close(fig)
        files.append(p)
    return files


def write_report(res: CampaignResult, *, jobs: int = 1) -> tuple[str, list[Path]]:
    """Write every file of the campaign; return the Markdown and the files written."""
    files = _write_campaign_csvs(res) + _campaign_plots(res)
    c = res.config
    air, imu = airdata_of(c), imu_of(c)
    # the campaigns fly the simulator: its air-data period turns the windows into samples
    n_eval, n_d = (f(air.fdi.aoa, sim_air_period_s()) for f in (window_n, detect_n))
    n_free = sum(1 for r in res.runs if not r.faulty)
    run_s = [r.wall_s for r in res.runs]
    veh_s = sum(r.duration_s for r in res.runs)
    md = [
        f"# Campaign `{res.preset_set}`: {res.n_runs} runs, seed {res.seed}",
        "",
        f"- command: `gcs-monitor evaluate --preset-set {res.preset_set} --runs {res.n_runs} "
        f"--jobs {jobs} --seed {res.seed}"
        f"{'' if res.declare_weather else ' --weather estimated'} --out {res.out_dir}`"
        + ("" if air.estimator == "cmhe" and imu.enabled and imu.ts.enabled else
           " (with the configuration below)"),
        f"- monitor: {monitor_label(res)}; J_th aoa {air.fdi.aoa.threshold / DEG2RAD:.3g} deg, "
        f"cas {air.fdi.cas.threshold / KT2MPS:.3g} kt, n_D/N_eval {n_d}/{n_eval}; baselines "
        f"use the same J_th on |y_i - median| (median vote: {n_d} consecutive samples, "
        f"latched; fixed threshold: 1 sample)",
        "- weather: " + ("each run's declared as its forecast (`[airdata.weather]`)"
                         if res.declare_weather else
                         "none declared; estimated from the flight (the defaults)"),
        f"- runs: {len(res.runs)} ({n_free} fault-free, {len(res.runs) - n_free} faulty), "
        f"{veh_s:.0f} s of flight; wall {res.wall_s:.0f} s with {jobs} job(s) "
        f"(mean {float(np.mean(run_s)) if run_s else math.nan:.1f} s per run)",
        "",
        "## Wan2018 Table IV metrics",
        "",
        metrics_markdown(res),
        "",
        "FAR over fault-free runs; MDR/FIR over runs with a fault in that group; delay from "
        "fault start to the first correct RAISED (largest over the run's faulty channels). "
        "Link and SET_LOST alarms are not counted.",
        "",
        "## Per fault kind",
        "",
        per_kind_markdown(res.runs),
        "",
        "## Reconstruction and output error",
        "",
        output_markdown(res.runs),
        "",
        "## Fault-free residuals vs thresholds",
        "",
        calibration_markdown(res),
        "",
        "## Plots",
        "",
    ]
    md += [f"![{p.stem}]({p.name})" for p in files if p.suffix == ".png"]
    text = "\n".join(md) + "\n"
    p = res.out_dir / "report.md"
    p.write_text(text)
    return text, [p] + files
