"""Held IMU samples: a bit-identical repeat of an instance's six values is no new measurement.

The assembler keeps the earlier sample (with its time) and counts the repeat; the IMU family
measures the effective rate from new samples only and steps no estimator on a held one
(telemetry/assembler.py, "Held IMU samples"; families/imu/family.py). Hand-built streams.
"""

from __future__ import annotations

import math

import numpy as np

from gcs_monitor.config import MonitorConfig
from gcs_monitor.convert import encode as enc
from gcs_monitor.families.base import FamilyContext
from gcs_monitor.families.imu.config import ImuFamilyConfig
from gcs_monitor.families.imu.family import ImuFamily
from gcs_monitor.families.imu.imu_ts import FAULT_CHANNELS
from gcs_monitor.fdi.records import Estimate
from gcs_monitor.link.decode import Decoder
from gcs_monitor.link.mav import mavlink
from gcs_monitor.monitor import Monitor
from gcs_monitor.pipeline import VehiclePipeline
from gcs_monitor.telemetry.assembler import FrameAssembler
from gcs_monitor.telemetry.frame import Frame, ImuSample

LAT_RAD, LON_RAD, ALT_M = 0.7, 0.2, 300.0


def _imu_values(k: int, inst: int = 0) -> tuple[tuple[float, float, float],
                                                 tuple[float, float, float]]:
    """Distinct noisy-looking values for new sample k of an instance."""
    rng = np.random.default_rng(1000 * inst + k)
    a = rng.normal(0.0, 0.05, 3) + (0.0, 0.0, -9.81)
    w = rng.normal(0.0, 0.002, 3)
    return (float(a[0]), float(a[1]), float(a[2])), (float(w[0]), float(w[1]), float(w[2]))


def _stream(duration_s: float, grid_hz: float, new_every: int, *, n_imu: int = 1,
            held_inst: tuple[int, ...] = (0,), frozen_from_s: float = math.inf,
            ) -> list[tuple[int, object]]:
    """Messages on a ``grid_hz`` grid (as a forward-filled resampled log): IMU instances in
    ``held_inst`` deliver a new sample every ``new_every`` grid points and repeat it between
    (from ``frozen_from_s`` on they only repeat); the others are new at every point; attitude
    and GPS velocity at every grid point."""
    out: list[tuple[int, object]] = []
    dt_us = round(1e6 / grid_hz)
    n = round(duration_s * grid_hz)
    for k in range(n):
        t_us = 1_000_000 + k * dt_us
        if k % round(grid_hz) == 0:
            out.append((t_us, enc.heartbeat_msg(mav_type=mavlink.MAV_TYPE_FIXED_WING,
                                                autopilot=mavlink.MAV_AUTOPILOT_GENERIC)))
        out.append((t_us, enc.global_position_msg(t_us, LAT_RAD, LON_RAD, ALT_M, 50.0,
                                                  (20.0, 0.0, 0.0))))
        for inst in range(n_imu):
            held = inst in held_inst
            j = k // new_every if held else k
            if held and t_us * 1e-6 - 1.0 >= frozen_from_s:
                j = round(frozen_from_s * grid_hz) // new_every
            a, w = _imu_values(j, inst)
            out.append((t_us, enc.highres_imu_msg(t_us, inst, a, w)))
        out.append((t_us, enc.attitude_msg(t_us, (0.0, 0.0, 0.0))))
    return out


def _frames(msgs: list[tuple[int, object]], asm: FrameAssembler, d: Decoder) -> list[Frame]:
    packer = enc.Packer(sysid=1, compid=1)
    frames: list[Frame] = []
    for _, m in msgs:
        for dm in d.feed(packer.pack(m), 0.0):  # type: ignore[arg-type]
            frames += asm.push(dm)
    return frames + asm.flush()


def test_a_repeated_sample_keeps_its_time_and_is_counted() -> None:
    d = Decoder()
    asm = FrameAssembler(stats=d.vehicle_stats(1))
    frames = _frames(_stream(2.0, 50.0, 5), asm, d)
    assert len(frames) == 100  # every grid point is a Frame: the pipeline's clock goes on
    new = [f for f in frames if f.imu_new]
    held = [f for f in frames if not f.imu_new]
    assert len(new) == 20 and len(held) == 80
    assert asm.stats.imu_held == 80
    for f in held:  # the held Frame carries the last new sample, with that sample's time
        s = f.primary_imu
        assert s is not None and s.t_us < f.t_us and (f.t_us - s.t_us) % 20_000 == 0
        assert f.t_us - s.t_us <= 4 * 20_000
    # new samples are 100 ms apart: 10 Hz effective on a 50 Hz grid
    assert np.all(np.diff([f.t_us for f in new]) == 100_000)


def test_values_that_differ_in_one_axis_are_new_samples() -> None:
    d = Decoder()
    asm = FrameAssembler(stats=d.vehicle_stats(1))
    msgs = []
    a, w = _imu_values(0)
    for k in range(10):
        t_us = 1_000_000 + k * 20_000
        # a stuck accelerometer axis (a jam fault): the other five still change
        w_k = (w[0] + 1e-6 * k, w[1], w[2])
        msgs.append((t_us, enc.highres_imu_msg(t_us, 0, a, w_k)))
    frames = _frames(msgs, asm, d)
    assert asm.stats.imu_held == 0 and all(f.imu_new for f in frames)


def test_a_primary_that_only_repeats_itself_is_switched_away_from() -> None:
    # IMU 0 freezes at 1 s (repeats bit for bit) while IMU 1 delivers: after stale_after_s the
    # assembler takes IMU 1 as primary, as for a silent one
    d = Decoder()
    asm = FrameAssembler(stats=d.vehicle_stats(1))
    frames = _frames(_stream(3.0, 50.0, 1, n_imu=2, held_inst=(0,), frozen_from_s=1.0), asm, d)
    switch = next(f for f in frames if f.primary == 1)
    frozen_at_us = 1_000_000 + 1_000_000
    assert frozen_at_us + 500_000 < switch.t_us <= frozen_at_us + 500_000 + 40_000
    assert asm.stats.primary_imu_switches == 1
    assert all(f.primary == 1 and f.imu_new for f in frames if f.t_us > switch.t_us)


class _Counting:
    """A scripted IMU estimator that counts its steps and the sample times it saw."""

    name = "imu_ts"

    def __init__(self) -> None:
        self.seen: list[int] = []

    def reset(self) -> None:
        pass

    def step(self, frame: Frame) -> Estimate:
        imu = frame.primary_imu
        self.seen.append(imu.t_us if imu is not None else -1)
        return Estimate(self.name, frame.t_us, faults=dict.fromkeys(FAULT_CHANNELS, 0.0),
                        reinit="start" if len(self.seen) == 1 else "",
                        reinit_warmup_s=0.5)


def _family_run(frames: list[Frame]) -> tuple[_Counting, VehiclePipeline, list]:
    cfg = ImuFamilyConfig()
    est = _Counting()
    fam = ImuFamily(cfg, FamilyContext(vehicle=1, stale_after_s=0.5),
                    estimators=[(est, cfg.ts.fdi)])  # type: ignore[list-item]
    p = VehiclePipeline(1, [fam])
    outs = [p.step(f) for f in frames]
    return est, p, outs


def _hand_frames(n: int, dt_us: int, new_every: int) -> list[Frame]:
    frames, sample = [], None
    for k in range(n):
        t_us = k * dt_us
        if k % new_every == 0:
            a, w = _imu_values(k)
            sample = ImuSample(t_us, 0, np.array(a), np.array(w))
        frames.append(Frame(t_us=t_us, imu=[sample], euler_rad=np.zeros(3), att_age_s=0.0,
                            gps_vel_ned_mps=np.array([20.0, 0.0, 0.0]), gps_age_s=0.0,
                            lat_rad=LAT_RAD, alt_msl_m=ALT_M))
    return frames


def test_the_family_steps_only_on_new_samples_and_judges_their_rate() -> None:
    # 100 Hz Frames, a new IMU sample every 2nd: the family steps at 50 Hz and sizes its
    # channel windows for 50 Hz (0.5 s = 25 samples)
    est, p, outs = _family_run(_hand_frames(800, 10_000, 2))
    assert len(est.seen) == 400 and len(set(est.seen)) == 400
    fam = p.families[0]
    assert isinstance(fam, ImuFamily)
    assert fam._est[0].monitors[0].p.rms.rms_window_n == 25
    assert outs[-1].coverage[0].state == "judging"


def test_an_imu_new_at_2_5_hz_on_a_20_hz_grid_is_too_slow() -> None:
    # the ALFA case: a 20 Hz grid whose IMU changes at 2.5 Hz
    est, _, outs = _family_run(_hand_frames(400, 50_000, 8))
    assert len(est.seen) == 50
    cov = outs[-1].coverage[0]
    assert cov.state == "degraded"
    assert cov.reason == "IMU at 2.5 Hz, below the 10 Hz the IMU family needs"


def test_a_frozen_single_imu_is_not_judged_and_the_family_says_why() -> None:
    frames = _hand_frames(1200, 10_000, 1)
    frozen = frames[600].imu[0]
    for f in frames[600:]:  # from 6 s on the only IMU repeats its last sample
        f.imu = [frozen]
    est, _, outs = _family_run(frames)
    assert len(est.seen) == 601
    cov = outs[-1].coverage[0]
    assert cov.state == "degraded"
    assert cov.reason.startswith("IMU 0 repeats its last sample for")


def test_alfa_imu_effective_rate_is_measured_from_its_held_samples(real_data_file) -> None:
    """ALFA's 20 Hz grid forward-fills an IMU that changes at ~2.5 Hz: the IMU family says so
    (before: 0 % coverage with 'innovations 478794x what its noise model expects')."""
    from gcs_monitor.link.logs import open_log

    path = real_data_file("carbonZ_2018-10-05-14-34-20_1_no_failure.csv")
    last = {}

    def on_step(sysid: int, frame: Frame, out) -> None:
        for c in out.coverage:
            last[c.family] = c

    mon = Monitor(MonitorConfig(), on_step=on_step)
    with open_log(path).source as src:
        for data, _ in src:
            mon.feed(data)
    mon.finish()
    reason = last["imu"].reason
    assert reason.startswith("IMU at ") and reason.endswith(
        " Hz, below the 10 Hz the IMU family needs"), reason
    rate_hz = float(reason.split()[2])
    assert 2.0 <= rate_hz <= 3.5  # data README: IMU columns change at ~2.5 Hz
    stats = mon.decoder.vehicle_stats(1)
    assert stats.imu_held > 0.8 * stats.per_type["HIGHRES_IMU"]
