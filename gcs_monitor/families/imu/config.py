"""Configuration of the IMU family: TOML section ``[imu]``.

Two fault-reconstructing estimators, each with the FDI thresholds of its own fault estimates
(their fault-free statistics differ): the Lu2016 ATSEKF on the GS-KM (``[imu.ts]``, on by
default) and the Atmaca2025 OTSEKF + HOSM differentiator (``[imu.hosm]``, off by default).
"""

from __future__ import annotations

from dataclasses import dataclass

from gcs_monitor.core.params import DEGPS, MPS2, param, section
from gcs_monitor.core.units import DEG2RAD
from gcs_monitor.families.imu.imu_hosm import ImuHosmConfig
from gcs_monitor.families.imu.imu_ts import ImuTsConfig
from gcs_monitor.fdi.config import ChannelSetConfig


def acc_channels(threshold_mps2: float) -> ChannelSetConfig:
    """Accelerometer fault channels: 0.5 s windows, 80 % of them above J_th confirm, a
    reconstructed fault clears after 2 s below half of J_th (it can return to zero)."""
    return ChannelSetConfig(threshold=threshold_mps2, window_s=0.5, detect_ratio=0.8,
                            clear_s=2.0, latch=False, noise_sigma=0.05, runaway_rate=1.0,
                            history_s=2.0, reclassify_s=0.5)


def gyro_channels(threshold_radps: float) -> ChannelSetConfig:
    """Gyro fault channels, as :func:`acc_channels`."""
    return ChannelSetConfig(threshold=threshold_radps, window_s=0.5, detect_ratio=0.8,
                            clear_s=2.0, latch=False, noise_sigma=0.05 * DEG2RAD,
                            runaway_rate=1.0 * DEG2RAD, history_s=2.0, reclassify_s=0.5)


# Thresholds: 1.5 x the worst fault-free RMS of each estimator's fault estimates over
# fault-free runs of every manoeuvre in turbulence (calibration seeds, not the evaluation
# seeds): `gcs-monitor evaluate --experiment imu_detection` (imu_ts) and
# `--experiment imu_detection_hosm` (imu_hosm: 0.6345 m/s^2, 0.2411 deg/s, rounded up) print them.
TS_ACC_MPS2 = 0.19
TS_GYRO_DEGPS = 0.35
HOSM_ACC_MPS2 = 0.64
HOSM_GYRO_DEGPS = 0.25


@dataclass(frozen=True, slots=True)
class ImuFdiSets:
    """The FDI channels of one estimator's six fault estimates."""

    acc: ChannelSetConfig = section(lambda: acc_channels(TS_ACC_MPS2),
                                    "accelerometer fault channels (x, y, z)", unit=MPS2)
    gyro: ChannelSetConfig = section(lambda: gyro_channels(TS_GYRO_DEGPS * DEG2RAD),
                                     "gyro fault channels (p, q, r)", unit=DEGPS)


@dataclass(frozen=True, slots=True)
class ImuTsSection:
    """Lu2016 ATSEKF / IOTSEKF IMU fault reconstruction."""

    enabled: bool = param(True, "run the Lu2016 estimator")
    estimator: ImuTsConfig = section(ImuTsConfig, "the Lu2016 estimator")
    fdi: ImuFdiSets = section(ImuFdiSets, "thresholds of its fault estimates")


@dataclass(frozen=True, slots=True)
class ImuHosmSection:
    """Atmaca2025 OTSEKF + HOSM IMU fault identification."""

    enabled: bool = param(False, "run the Atmaca2025 estimator")
    estimator: ImuHosmConfig = section(ImuHosmConfig, "the Atmaca2025 estimator")
    fdi: ImuFdiSets = section(
        lambda: ImuFdiSets(acc=acc_channels(HOSM_ACC_MPS2),
                           gyro=gyro_channels(HOSM_GYRO_DEGPS * DEG2RAD)),
        "thresholds of its fault estimates")


@dataclass(frozen=True, slots=True)
class ImuFamilyConfig:
    """IMU sensor faults reconstructed from GPS velocity and attitude (Lu2016, Atmaca2025)."""

    enabled: bool = param(True, "monitor the IMU family")
    warmup_s: float = param(5.0, "fault estimates are judged this long after an estimator "
                            "becomes available again without a re-initialisation notice")
    no_data_window_s: float = param(0.5, "an IMU instance silent this long while another "
                                    "delivers raises no_data; 0 turns the check off")
    max_inconsistency: float = param(20.0, "an estimator's fault estimates are not judged while "
                                     "its normalised innovation squared averages more than this "
                                     "(1 for a noise model that fits the vehicle; calibrate "
                                     "fits it); 0 turns the check off")
    consistency_window_s: float = param(10.0, "span of that average", positive=True)
    reference_window_s: float = param(1.0, "the GPS position is checked against its own "
                                      "integrated velocity over this span (at least 3 GPS "
                                      "periods); what they disagree by beyond the measured "
                                      "position noise, per second of the span, is added to "
                                      "the accelerometer channels' J_th (a reference "
                                      "correcting itself, gating.py item 3); 0 turns the "
                                      "check off")
    reference_hold_s: float = param(2.0, "that allowance is the largest of this last span "
                                    "(the fault estimates absorbed the reference's "
                                    "corrections and re-converge)", positive=True)
    ts: ImuTsSection = section(ImuTsSection, "Lu2016 ATSEKF on the GS-KM")
    hosm: ImuHosmSection = section(ImuHosmSection, "Atmaca2025 OTSEKF + HOSM")
