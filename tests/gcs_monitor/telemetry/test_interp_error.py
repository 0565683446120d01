"""The assembler's IMU-measured error of the interpolated GPS velocity (samples.imu_chord),
through MAVLink: level, heading north (NED = FRD), specific force with a constant jerk."""

from __future__ import annotations

import numpy as np

from gcs_monitor.config import MonitorConfig
from gcs_monitor.config.loader import config_from_dict
from gcs_monitor.link.decode import Decoder
from gcs_monitor.monitor import Monitor
from gcs_monitor.telemetry.assembler import FrameAssembler
from tests.helpers.mavgen import G0, MavGen

JERK = 2.0  # m/s^3 along north and east


class _Jerk(MavGen):
    @staticmethod
    def acc_frd(t: float, inst: int = 0) -> tuple[float, float, float]:
        return (JERK * (t - 5.0), -JERK * (t - 5.0), -G0)

    @staticmethod
    def euler(t: float) -> tuple[float, float, float]:
        return (0.0, 0.0, 0.0)


def _frames(gps_hz: int, *, interp_error: bool = True) -> dict[int, object]:
    d = Decoder()
    a = FrameAssembler.aligned(None, d.vehicle_stats(1), interp_error=interp_error)
    out = []
    for _, p in _Jerk(gps_rate_hz=gps_hz, n_imu=1).packets(6.0):
        for m in d.feed(p, 0.0):
            out += a.push(m)
    out += a.flush()
    return {f.t_us: f for f in out}


def test_one_hz_gps_error_is_the_constant_jerk_chord_error():
    # e(tau) = j tau (T - tau) / 2 (samples.imu_chord): 0.25 m/s at mid-interval for j = 2 m/s^3
    # and T = 1 s, 0.1875 m/s a quarter into it, zero on a GPS sample; no vertical error
    f = _frames(1)
    for t_us, want in ((9_500_000, 0.25), (9_250_000, 0.1875), (8_750_000, 0.1875)):
        e = f[t_us].gps_interp_err_ned_mps
        assert e is not None and not f[t_us].gps_held
        np.testing.assert_allclose(e, [want, -want, 0.0], atol=1e-4)
    e = f[9_000_000].gps_interp_err_ned_mps
    assert e is None or np.allclose(e, 0.0, atol=1e-4)


def test_ten_hz_gps_error_is_a_hundred_times_smaller():
    # T = 0.1 s: j T^2 / 8 = 0.0025 m/s at mid-interval, a quarter of the GPS noise of Table 1
    f = _frames(10)
    np.testing.assert_allclose(f[9_050_000].gps_interp_err_ned_mps, [0.0025, -0.0025, 0.0],
                               atol=1e-5)


def test_computed_only_when_a_family_reads_it():
    # FDI-only monitors (no imu_ts with gps_imu_shape) skip the IMU chords of every GPS interval
    f = _frames(1, interp_error=False)
    assert all(fr.gps_interp_err_ned_mps is None for fr in f.values())  # type: ignore[attr-defined]
    assert any(fr.gps_vel_ned_mps is not None for fr in f.values())  # type: ignore[attr-defined]
    fdi = MonitorConfig().with_family("airdata", estimator="none")
    for name in ("imu", "yaw_rate", "actuators"):
        fdi = fdi.with_family(name, enabled=False)
    no_shape = config_from_dict({"imu": {"ts": {"estimator": {"gps_imu_shape": False}}}})
    for cfg, reads in ((MonitorConfig(), True), (fdi, False), (no_shape, False)):
        mon = Monitor(cfg)
        for _, p in _Jerk(gps_rate_hz=1, n_imu=1).packets(3.0):
            mon.feed(p)
        (v,) = mon.vehicles.values()
        assert v.pipeline is not None and v.assembler.interp_error is reads


def test_flat_dcm_and_stacked_matmul_are_bit_identical_to_dcm_ned_frd():
    # _interp_error rotates all samples of an interval in one stacked matmul of flat DCMs: the
    # values must be those of dcm_ned_frd(...) @ acc per sample, to the bit
    from gcs_monitor.core.frames import dcm_ned_frd
    from gcs_monitor.telemetry.assembler import _dcm_ned_frd_flat

    rng = np.random.default_rng(5)
    eul = rng.uniform(-3.3, 3.3, (3000, 3))
    acc = rng.normal(0.0, 10.0, (3000, 3))
    flat = np.array([_dcm_ned_frd_flat(*e) for e in eul.tolist()])
    ref = np.array([dcm_ned_frd(*e) for e in eul.tolist()])
    assert flat.tobytes() == ref.reshape(-1, 9).tobytes()
    stacked = np.matmul(flat.reshape(-1, 3, 3), acc[:, :, None])[:, :, 0]
    one_by_one = np.array([c @ a for c, a in zip(ref, acc, strict=True)])
    assert stacked.tobytes() == one_by_one.tobytes()
