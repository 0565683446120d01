"""One run through the MAVLink path (gcs_monitor.evaluation.runs): sim -> bytes -> Monitor."""

from __future__ import annotations

import numpy as np

from gcs_monitor.evaluation.configs import imu_config
from gcs_monitor.evaluation.runs import simulate_imu
from gcs_monitor.evaluation.scenarios import preset
from gcs_monitor.evaluation.scoring import detection_summary, rmse, score_masks


def test_lu2016_calm_20s_through_mavlink_all_channels_alarmed() -> None:
    """20 s of lu2016_calm (faults from 10 s) with the default monitor estimator and thresholds:
    all six channels alarm within 3 s of the fault start (the drift: after crossing the
    threshold), none before it, and the GS-KM ATSEKF reconstruction is within bounds from the
    Lu2016 synthetic truth (docs/results.md, "Synthetic truth": f_Az 0.41 m/s^2, f_q 0.146 deg/s)
    with margin for the 10-20 s window."""
    sc = preset("lu2016_calm", duration_s=20.0)
    run_cfg = imu_config()
    run = simulate_imu(sc, run_cfg)
    d = detection_summary(run)
    assert d["missed"] == 0 and d["false"] == 0
    # the 0.1 m/s^3 drift of f_Ay crosses the 0.5 m/s^2 default threshold after 5 s
    thr_ay = run_cfg.family("imu").ts.fdi.acc.threshold / 0.1
    bounds = [3.0, thr_ay + 1.5, 3.0, 3.0, 3.0, 3.0]
    assert all(0.0 < x < b for x, b in zip(d["delay_s"], bounds, strict=True)), d["delay_s"]
    inf, quiet = score_masks(run)
    err = run.f_hat["imu_ts"] - run.f_true
    r_fault = rmse(err, inf)
    r_quiet = rmse(err, quiet)
    assert np.all(r_fault[:3] < [0.2, 0.2, 0.6]), r_fault
    assert np.all(r_fault[3:] < [0.1, 0.25, 0.15]), r_fault
    assert np.all(r_quiet[:3] < 0.1) and np.all(r_quiet[3:] < 0.05), r_quiet
