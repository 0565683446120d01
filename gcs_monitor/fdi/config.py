"""Configuration of FDI sets and channels, in seconds, and its conversion to sample counts.

A family declares one :class:`ChannelSetConfig` per kind of reconstructed-fault channel (IMU
accelerometer and gyro faults) and one :class:`RedundantSetConfig` per redundant sensor set
(triplex AoA, triplex CAS). Windows are given in seconds; :func:`channel_params` and
:func:`set_params` turn them into the sample counts of the monitors with the *measured* sample
period of the stream being judged (Wan2018's N_eval = 10 is 0.5 s of its 20 Hz air data).
Thresholds and the classifier's noise and runaway rate are SI; the TOML key carries the
set's display unit (``threshold_deg`` for AoA, ``threshold_kts`` for CAS, ...).
"""

from __future__ import annotations

from dataclasses import dataclass

from gcs_monitor.core.params import param
from gcs_monitor.fdi.alarms import AlarmParams
from gcs_monitor.fdi.classify import ClassifierShape
from gcs_monitor.fdi.confirmation import ConfirmationParams
from gcs_monitor.fdi.monitor import ChannelMonitorParams, SetMonitorParams
from gcs_monitor.fdi.residuals import RmsWindowParams

STUCK_MIN_SAMPLES = 4  # SetMonitorParams.stuck_n's least window


def samples_in(window_s: float, period_s: float, *, minimum: int = 1) -> int:
    """Samples of a stream of period ``period_s`` in ``window_s`` (at least ``minimum``)."""
    return max(minimum, round(window_s / period_s))


@dataclass(frozen=True, slots=True)
class ChannelSetConfig:
    """One kind of monitored channel: residual RMS window, threshold, confirmation, classifier
    (Wan2018 sec. III-A: eq. 18 and n_D of N_eval)."""

    threshold: float = param(1.0, "J_th: residual RMS above which a sample counts as exceeded "
                             "(Wan2018 sec. VI-B sets it from the worst fault-free J)",
                             key="threshold_{u}", positive=True)
    threshold_per_turbulence: float = param(
        0.0, "growth of J_th per m/s of Dryden turbulence sigma (weather in [airdata.weather]); "
        "0 = one fixed J_th as Wan2018", key="threshold_slope_{u}_per_mps")
    window_s: float = param(0.5, "residual RMS window and confirmation window N_eval "
                            "(Wan2018 eq. 18: N_eval = 10 samples of 20 Hz air data)",
                            positive=True)
    min_window_samples: int = param(10, "the window holds at least this many samples (it "
                                    "grows beyond window_s on a slow stream: an RMS and an "
                                    "n_D-of-N count over fewer samples are too noisy to judge "
                                    "with the same J_th; Wan2018's N_eval)", positive=True)
    detect_ratio: float = param(0.5, "n_D / N_eval: share of the window's samples above J_th "
                                "that confirms a fault (Wan2018 gives no n_D)", positive=True)
    clear_ratio: float = param(0.5, "clear level as a fraction of J_th (hysteresis)",
                               positive=True)
    clear_s: float = param(10.0, "time below the clear level before a fault clears (when not "
                           "latched)", positive=True)
    latch: bool = param(True, "keep a confirmed fault for good (Wan2018 never re-admits a "
                        "sensor)")
    noise_sigma: float = param(0.1, "1-sigma sensor noise the classifier compares "
                               "oscillations and noise faults with", key="noise_sigma_{u}",
                               positive=True)
    runaway_rate: float = param(1.0, "rate that separates a drift from a runaway in the "
                                "classifier", key="runaway_rate_{ur}", positive=True)
    history_s: float = param(10.0, "residual history the classifier looks at", positive=True)
    reclassify_s: float = param(2.5, "time between two re-classifications of an active alarm",
                                positive=True)

    def __post_init__(self) -> None:
        if not 0.0 < self.detect_ratio <= 1.0:
            raise ValueError(f"detect_ratio must be in (0, 1], got {self.detect_ratio}")
        if not 0.0 < self.clear_ratio <= 1.0:
            raise ValueError(f"clear_ratio must be in (0, 1], got {self.clear_ratio}")


@dataclass(frozen=True, slots=True)
class RedundantSetConfig(ChannelSetConfig):
    """A redundant sensor set (Wan2018's triplex AoA and CAS): the channel settings plus the
    set's own checks and fusion options."""

    stuck_window_s: float = param(0.5, "frozen-signal (jam) check window; 0 turns it off "
                                  "(ours: Wan2018's residual sees a jam only once the true value "
                                  "has moved by J_th)")
    no_data_window_s: float = param(0.5, "an instance without a valid value for this long while "
                                    "a peer delivers is isolated as no_data; 0 turns it off")
    restart_peers: bool = param(True, "restart the healthy peers' windows when an instance is "
                                "isolated (ours; false = Wan2018's scheme)")
    equal_pair_weights: bool = param(False, "equal eq. 19 weights for the last two healthy "
                                     "instances while both are below J_th (ours)")

    def __post_init__(self) -> None:
        ChannelSetConfig.__post_init__(self)
        if 0.0 < self.stuck_window_s < 0.5:
            raise ValueError(f"stuck_window_s must be 0 (off) or at least 0.5 s, got "
                             f"{self.stuck_window_s}")


def scheduled_threshold(cfg: ChannelSetConfig, turbulence_sigma_mps: float) -> float:
    """J_th of a set for a Dryden intensity (SI): the fault-free residual floor of the air-data
    sets grows with the gusts the one-step prediction cannot foresee."""
    return cfg.threshold + cfg.threshold_per_turbulence * turbulence_sigma_mps


def _confirmation(cfg: ChannelSetConfig, window_n: int, period_s: float) -> ConfirmationParams:
    return ConfirmationParams(detect_n=max(1, round(cfg.detect_ratio * window_n)),
                              eval_n=window_n, clear_ratio=cfg.clear_ratio,
                              clear_n=samples_in(cfg.clear_s, period_s), latch=cfg.latch)


def window_samples(cfg: ChannelSetConfig, period_s: float) -> int:
    """N_eval at the measured period: ``window_s`` of samples, at least ``min_window_samples``."""
    return samples_in(cfg.window_s, period_s, minimum=cfg.min_window_samples)


def channel_params(cfg: ChannelSetConfig, period_s: float, *,
                   alarm: AlarmParams | None = None,
                   classifier: ClassifierShape | None = None) -> ChannelMonitorParams:
    """The monitor parameters of one channel sampled every ``period_s`` (measured)."""
    n = window_samples(cfg, period_s)
    return ChannelMonitorParams(
        threshold=cfg.threshold, noise_sigma=cfg.noise_sigma, runaway_rate_per_s=cfg.runaway_rate,
        dt_s=period_s, rms=RmsWindowParams(rms_window_n=n),
        confirmation=_confirmation(cfg, n, period_s),
        history_n=samples_in(cfg.history_s, period_s, minimum=4),
        reclassify_every_n=samples_in(cfg.reclassify_s, period_s),
        alarm=alarm or AlarmParams(), classifier=classifier or ClassifierShape(),
    )


def set_params(cfg: RedundantSetConfig, period_s: float, *, threshold: float | None = None,
               alarm: AlarmParams | None = None,
               classifier: ClassifierShape | None = None) -> SetMonitorParams:
    """The monitor parameters of one redundant set sampled every ``period_s`` (measured);
    ``threshold`` replaces ``cfg.threshold`` (a scheduled J_th)."""
    n = window_samples(cfg, period_s)
    return SetMonitorParams(
        threshold=cfg.threshold if threshold is None else threshold,
        noise_sigma=cfg.noise_sigma, runaway_rate_per_s=cfg.runaway_rate, dt_s=period_s,
        rms=RmsWindowParams(rms_window_n=n), confirmation=_confirmation(cfg, n, period_s),
        history_n=samples_in(cfg.history_s, period_s, minimum=4),
        reclassify_every_n=samples_in(cfg.reclassify_s, period_s),
        # the frozen-signal test needs a few changes to compare: at least 4 samples (0.8 s of a
        # 5 Hz stream for the 0.5 s default)
        stuck_n=samples_in(cfg.stuck_window_s, period_s, minimum=STUCK_MIN_SAMPLES)
        if cfg.stuck_window_s > 0.0 else 0,
        no_data_n=samples_in(cfg.no_data_window_s, period_s)
        if cfg.no_data_window_s > 0.0 else 0,
        restart_peers=cfg.restart_peers,
        alarm=alarm or AlarmParams(), classifier=classifier or ClassifierShape(),
    )
