"""A deterministic synthetic recording for the dashboard test (and the docs screenshot).

:func:`write_synthetic_rrd` drives the real :class:`~gcs_monitor.sinks.rerun_sink.RerunSink`
with synthetic Frames, set/channel status and alarms, seeded, so every dashboard view has data.
``tests/dashboards/test_dashboard_screenshot.py`` renders it (``GCS_UPDATE_SCREENSHOT=1`` copies
the result to ``docs/img/dashboard.png``).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from dashboards.blueprints import default_blueprint
from gcs_monitor.core.types import ChannelId
from gcs_monitor.fdi.events import (
    AlarmEvent,
    AlarmKind,
    AlarmState,
    ChannelStatus,
    FaultType,
    SetStatus,
)
from gcs_monitor.fdi.records import Estimate, StepOutput
from gcs_monitor.sinks.rerun_sink import RerunSink
from gcs_monitor.telemetry.frame import Frame, ImuSample


def write_synthetic_rrd(
    path: Path,
    *,
    vehicle: int = 1,
    duration_s: float = 30.0,
    seed: int = 0,
    fault_t_s: float = 12.0,
) -> dict[str, Any]:
    """Drive a real RerunSink with a deterministic synthetic flight and write ``path``.

    A 25 m/s circle (radius 300 m, 20 deg bank), triplex AoA with a +2 deg bias on vane 2 from
    ``fault_t_s``, and a +0.5 m/s^2 accelerometer-x bias on IMU 0 from ``fault_t_s + 3 s`` that
    a first-order "reconstruction" follows. RMS, weights and alarms come from simple stand-ins
    (a moving RMS against the median, inverse-RMS weights) so every dashboard view has data; it is
    a demo of the display, not of the FDI algorithms.

    Returns counters: frames, events and the sink's publish statistics.
    """
    rng = np.random.default_rng(seed)
    dt_s = 0.01
    n = round(duration_s / dt_s)
    speed_mps, radius_m, bank_rad = 25.0, 300.0, math.radians(20.0)
    lat0, lon0, alt0 = math.radians(47.0), math.radians(8.0), 500.0
    earth_r = 6_367_000.0
    aoa_bias_rad, acc_bias_mps2 = math.radians(2.0), 0.5
    rms_window = 50
    aoa_th_rad, acc_th_mps2 = math.radians(0.8), 0.2
    resid_hist = np.zeros((rms_window, 3))
    acc_fault_hat = 0.0
    raised_aoa = raised_acc = False
    n_events = 0
    with RerunSink(vehicle, rrd_path=path, recording_id=f"synthetic-{vehicle}-{seed}",
                   blueprint=default_blueprint(vehicle)) as sink:
        for k in range(n):
            t_s = k * dt_s
            t_us = round(t_s * 1e6)
            psi = speed_mps / radius_m * t_s
            north, east = radius_m * math.sin(psi), radius_m * (1 - math.cos(psi))
            aoa_true = 0.06 + 0.01 * math.sin(0.7 * t_s)
            aoa = aoa_true + rng.normal(0.0, math.radians(0.15), 3)
            if t_s >= fault_t_s:
                aoa[2] += aoa_bias_rad
            acc = np.array([0.3, 0.0, -9.81 / math.cos(bank_rad)]) + rng.normal(0, 0.05, 3)
            acc_fault = acc_bias_mps2 if t_s >= fault_t_s + 3.0 else 0.0
            acc[0] += acc_fault
            gyro = np.array([0.0, 0.02, speed_mps / radius_m]) + rng.normal(0, 0.002, 3)
            frame = Frame(
                t_us=t_us,
                imu=[ImuSample(t_us, 0, acc, gyro)],
                euler_rad=np.array([bank_rad, aoa_true, psi]),
                lat_rad=lat0 + north / earth_r,
                lon_rad=lon0 + east / (earth_r * math.cos(lat0)),
                alt_msl_m=alt0 + 5.0 * math.sin(0.2 * t_s),
                aoa_rad=aoa,
            )
            cas = 25.0 + 0.3 * math.sin(0.5 * t_s) + rng.normal(0.0, 0.1, 3)
            frame.cas_mps = cas
            cas_med = float(np.median(cas))
            cas_set = SetStatus(
                name="cas",
                t_us=t_us,
                measured=tuple(cas),
                reference=cas_med,
                fused=cas_med,
                weights=(1 / 3, 1 / 3, 1 / 3),
                rms=(0.1, 0.1, 0.1),
                threshold=1.0,
                faulty=(False, False, False),
                configuration="triplex",
            )
            fused_med = float(np.median(aoa))
            resid_hist[k % rms_window] = aoa - fused_med
            rms = np.sqrt(np.mean(resid_hist**2, axis=0))
            w = 1.0 / np.maximum(rms, 1e-4)
            w /= w.sum()
            faulty = tuple(bool(r > aoa_th_rad) for r in rms)
            aoa_set = SetStatus(
                name="aoa",
                t_us=t_us,
                measured=tuple(aoa),
                reference=fused_med,
                fused=float(w @ aoa),
                weights=tuple(w),
                rms=tuple(rms),
                threshold=aoa_th_rad,
                faulty=faulty,
                configuration="triplex" if not any(faulty) else "duplex",
            )
            acc_fault_hat += dt_s / 0.8 * (acc_fault - acc_fault_hat)  # 0.8 s first-order lag
            ch_acc = [ChannelId("acc", 0, ax) for ax in "xyz"]
            chans = [
                ChannelStatus(
                    ch,
                    t_us,
                    value=acc_fault_hat if ch.axis == "x" else 0.0,
                    rms=abs(acc_fault_hat) if ch.axis == "x" else 0.02,
                    threshold=acc_th_mps2,
                    faulty=False,
                    estimator="imu_ts",
                )
                for ch in ch_acc
            ]
            est = Estimate(
                name="imu_ts",
                t_us=t_us,
                states={
                    "vel_ned_mps": np.array(
                        [speed_mps * math.cos(psi), speed_mps * math.sin(psi), 0.0]
                    )
                },
                faults={ch_acc[0]: acc_fault_hat},
                virtual={
                    ch: float(acc[i] - (acc_fault_hat if i == 0 else 0.0))
                    for i, ch in enumerate(ch_acc)
                },
            )
            events: list[AlarmEvent] = []
            if faulty[2] and not raised_aoa:
                raised_aoa = True
                events.append(
                    AlarmEvent(
                        t_us,
                        ChannelId("aoa", 2),
                        AlarmState.RAISED,
                        AlarmKind.SENSOR_FAULT,
                        FaultType.BIAS,
                        float(aoa[2] - fused_med),
                        float(rms[2]),
                        aoa_th_rad,
                        "voting",
                        "vane 2 disagrees",
                        vehicle,
                    )
                )
            if acc_fault_hat > acc_th_mps2 and not raised_acc:
                raised_acc = True
                events.append(
                    AlarmEvent(
                        t_us,
                        ch_acc[0],
                        AlarmState.RAISED,
                        AlarmKind.SENSOR_FAULT,
                        FaultType.BIAS,
                        acc_fault_hat,
                        acc_fault_hat,
                        acc_th_mps2,
                        "imu_ts",
                        "accelerometer x bias",
                        vehicle,
                    )
                )
            n_events += len(events)
            sink.log_true_faults(t_us, {ch_acc[0]: acc_fault})
            sink.publish(frame, StepOutput(events=events, estimates=[est],
                                           sets=[aoa_set, cas_set], channels=chans))
            if k % 100 == 0:
                sink.update_health({"alarms_active": int(raised_aoa) + int(raised_acc)})
        stats = {
            "frames": n,
            "events": n_events,
            "publish": sink.n_publish,
            "rows_sent": sink.n_rows_sent,
        }
    return stats
