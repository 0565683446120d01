"""Configuration of the actuator family: TOML section ``[actuators]``.

The family composes tiers. The servo tier (``[actuators.servo]``, :mod:`.servo`) reconstructs
each surface's servo faults (Lu2017) where the telemetry reports surface and rod positions. The
aircraft tier (``[actuators.aircraft]``) judges the surfaces
and the engine from what every autopilot sends: servo outputs or setpoints, body rates,
specific force, airspeed and throttle. Its thresholds are on normalised residuals (a residual
divided by its own running RMS over healthy flight), so one configuration serves airframes and
weathers whose residual levels differ; the defaults were set on fault-free flights only
(``gcs-monitor evaluate --experiment actuators_sim`` and ``actuators_alfa`` print how).
"""

from __future__ import annotations

from dataclasses import dataclass

from gcs_monitor.core.params import param, section
from gcs_monitor.core.units import DEG2RAD
from gcs_monitor.families.actuators.servo import ServoTierConfig

SURFACES = ("aileron", "elevator", "rudder")
# Default J_th: 1.25 x the worst J after the warm-up over 26 fault-free simulated flights of both
# airframes (6 transport presets with their faults removed, 6 `fault_free` transport flights at
# 10 Hz servo outputs; 14 `actuators_fault_free` UAV flights at 50 Hz; calibration seed 101;
# every manoeuvre, calm to 3.5 m/s turbulence), rounded up: worst J 8.56 (surfaces: the
# transport's zero-g parabola; 3.56 on the UAV), 1.80 (engine), 11.29 (effectiveness, a UAV
# flight). docs/results.md, "Actuator family".
SURFACE_J_TH = 11.0
ENGINE_J_TH = 2.3
EFFECTIVENESS_J_TH = 14.2
ACTUATORS = (*SURFACES, "engine")
COMMAND_SOURCES = ("auto", "servo", "setpoint")


@dataclass(frozen=True, slots=True)
class ServoMapConfig:
    """Which SERVO_OUTPUT_RAW channel drives what, and how its pulse maps to a command."""

    aileron_channel: int = param(1, "servo output (1-16) of the aileron; 0 = not on the "
                                 "outputs (ArduPlane default: 1)")
    elevator_channel: int = param(2, "servo output of the elevator (ArduPlane default: 2)")
    rudder_channel: int = param(3, "servo output of the rudder (ArduPlane default: 4; the "
                                "simulator's: 3)")
    throttle_channel: int = param(4, "servo output of the throttle (ArduPlane default: 3; the "
                                  "simulator's: 4); 0 = take VFR_HUD's throttle")
    pwm_center_us: float = param(1500.0, "surface pulse at zero deflection, µs", positive=True)
    pwm_half_range_us: float = param(500.0, "surface pulse change for full deflection, µs",
                                     positive=True)
    throttle_min_us: float = param(1000.0, "throttle pulse at idle, µs", positive=True)
    throttle_max_us: float = param(2000.0, "throttle pulse at full throttle, µs", positive=True)
    max_deflection_rad: tuple[float, float, float] = param(
        (0.4, 0.4, 0.4), "aileron, elevator, rudder deflection at full pulse, rad (the "
        "simulated UAV's; reported stuck positions scale with it)", unit="si")

    def channels(self) -> tuple[int, int, int]:
        return (self.aileron_channel, self.elevator_channel, self.rudder_channel)

    def __post_init__(self) -> None:
        for name in ("aileron_channel", "elevator_channel", "rudder_channel",
                     "throttle_channel"):
            if not 0 <= getattr(self, name) <= 16:
                raise ValueError(f"{name} must be 0..16, got {getattr(self, name)}")
        if self.throttle_max_us <= self.throttle_min_us:
            raise ValueError("throttle_max_us must be above throttle_min_us")


@dataclass(frozen=True, slots=True)
class ModelConfig:
    """The per-axis models identified online by recursive least squares (Keipour 2019)."""

    reference_memory_s: float = param(600.0, "memory of the reference model (what healthy "
                                      "flight looks like); frozen while a fault is suspected",
                                      positive=True)
    tracking_memory_s: float = param(5.0, "memory of the tracking model, whose effectiveness "
                                     "is compared with the reference's", positive=True)
    sigma_memory_s: float = param(30.0, "memory of the residual RMS that normalises each "
                                  "axis's residual", positive=True)
    initial_covariance: float = param(100.0, "initial RLS covariance (diagonal)", positive=True)
    covariance_trace_max: float = param(1.0e4, "bound on the RLS covariance trace (no wind-up "
                                        "without excitation)", positive=True)
    warmup_s: float = param(8.0, "an axis is judged this long after its model started "
                            "(the reference model converges)", positive=True)
    convergence_s: float = param(20.0, "after the warm-up, the checks' values are divided by "
                                 "a factor falling linearly to 1 over this time (the reference "
                                 "model has not seen every manoeuvre yet)", positive=True)
    convergence_factor: float = param(2.0, "that factor at the end of the warm-up",
                                      positive=True)
    airspeed_ref_mps: float = param(0.0, "airspeed the dynamic-pressure scaling refers to; 0 = "
                                    "the first measured airspeed")
    min_airspeed_mps: float = param(8.0, "below this airspeed the surfaces are not judged (on "
                                    "the ground, stalled)")
    min_rate_sigma_radps: float = param(0.005, "floor of the body-rate residual RMS",
                                        positive=True)
    min_accel_sigma_mps2: float = param(0.02, "floor of the specific-force residual RMS",
                                        positive=True)
    identified_se: float = param(3.0, "a surface is judged once its model has identified the "
                                 "command's effect: |b| above this many standard errors "
                                 "sigma sqrt(P_bb) (a surface the autopilot has not moved yet "
                                 "cannot be judged); 0 turns the check off")
    freeze_ratio: float = param(0.75, "the reference models and residual RMS stop learning "
                                "while any check's J is above this share of its J_th",
                                positive=True)
    huber_c: float = param(3.0, "Huber weight of a sample in the models: min(1, c / |e / "
                           "sigma|) (one glitch cannot move them)", positive=True)
    max_setpoint_error_rad: float = param(20.0 * DEG2RAD, "setpoint errors are clipped here "
                                          "(the autopilot's rate demand saturates)",
                                          positive=True)
    max_energy_error_mps: float = param(10.0, "energy errors (aspd_error + g alt_error / V) are "
                                        "clipped here (the throttle saturates)", positive=True)
    max_step_s: float = param(1.0, "a longer gap between two control samples restarts the "
                              "models' lagged terms", positive=True)
    engine_lag_max_s: float = param(3.6, "the engine's thrust follows its throttle with a lag "
                                    "(a turbofan spools up in seconds, a propeller in a "
                                    "tenth): with servo outputs, engine models on the "
                                    "throttle through lags of 0, 1/9, 1/3 and 1 x this learn "
                                    "side by side and the best fit judges; 0: no lag")


@dataclass(frozen=True, slots=True)
class ResidualCheckConfig:
    """Residual RMS window (Wan2018 eq. 18 on the normalised residual), threshold and
    n_D-of-N confirmation, windows in seconds."""

    threshold: float = param(SURFACE_J_TH, "J_th on the RMS of the normalised residual "
                             "(dimensionless: multiples of the axis's healthy residual RMS)",
                             positive=True)
    smoothing_s: float = param(0.0, "time constant of an exponential smoothing of the value "
                               "before the RMS window (a persistent fault is a bias: smoothing "
                               "divides the noise by ~sqrt(2 smoothing_s / period)); 0 = none")
    window_s: float = param(1.0, "RMS and confirmation window", positive=True)
    detect_ratio: float = param(0.6, "share of the window's samples above J_th that confirms",
                                positive=True)
    clear_ratio: float = param(0.5, "clear level as a fraction of J_th", positive=True)
    clear_s: float = param(5.0, "time below the clear level before an alarm clears",
                           positive=True)
    latch: bool = param(False, "keep a confirmed actuator fault for good")

    def __post_init__(self) -> None:
        if not 0.0 < self.detect_ratio <= 1.0:
            raise ValueError(f"detect_ratio must be in (0, 1], got {self.detect_ratio}")
        if not 0.0 < self.clear_ratio <= 1.0:
            raise ValueError(f"clear_ratio must be in (0, 1], got {self.clear_ratio}")


@dataclass(frozen=True, slots=True)
class ClassifyConfig:
    """Which command no longer acts, and how: ``kappa``, the share of the command that still
    acts (the tracking model's effectiveness over the reference's), and the stuck position
    that explains the response over the alarm's history."""

    history_s: float = param(3.0, "span of the history the classification fits", positive=True)
    stuck_gain: float = param(0.35, "kappa (the share of the command that still acts) below "
                              "which the actuator is stuck rather than less effective",
                              positive=True)
    zero_position_ratio: float = param(0.1, "a surface stuck within this share of its full "
                                       "deflection is reported stuck at zero", positive=True)
    reclassify_s: float = param(2.0, "time between two classifications of an active alarm",
                                positive=True)
    engine_min_loss: float = param(0.25, "an engine alarm is raised only when at least this "
                                   "share of the thrust its model gives at the throttle is "
                                   "missing over the history (the model's resolution: healthy "
                                   "engines read up to 13 % in the triplex campaign's "
                                   "manoeuvres); without a throttle, any mean deficit",
                                   positive=True)


@dataclass(frozen=True, slots=True)
class AircraftFdiConfig:
    """The residual checks of the surfaces and of the engine, and their isolation."""

    surface: ResidualCheckConfig = section(ResidualCheckConfig,
                                           "aileron, elevator and rudder axes")
    engine: ResidualCheckConfig = section(
        lambda: ResidualCheckConfig(threshold=ENGINE_J_TH, smoothing_s=1.0, window_s=2.0),
        "the engine (thrust deficit: only a specific force below the model counts)")
    effectiveness: ResidualCheckConfig = section(
        lambda: ResidualCheckConfig(threshold=EFFECTIVENESS_J_TH, window_s=1.0),
        "every actuator's effectiveness: the tracking model's loss against the reference "
        "model's, in standard errors (one-sided: only a loss counts)")
    isolation_ratio: float = param(0.5, "a confirmed axis raises only if its J/J_th is at least "
                                   "this share of the largest confirmed axis's (the axis whose "
                                   "command no longer acts dominates)", positive=True)
    second_fault_ratio: float = param(1.5, "while an actuator alarm is active, another axis "
                                      "raises only if its J/J_th is at least this multiple of "
                                      "the active axis's (a fault disturbs the other axes' "
                                      "models too, later than its own)", positive=True)
    classify: ClassifyConfig = section(ClassifyConfig, "fault class and magnitude")


@dataclass(frozen=True, slots=True)
class AircraftTierConfig:
    """Surfaces and engine from servo outputs or setpoints, body rates, specific force,
    airspeed and throttle: per-axis RLS models (Keipour 2019), their residuals and
    effectiveness through the shared FDI layer."""

    enabled: bool = param(True, "run the aircraft tier")
    command_source: str = param("auto", "what an axis's model takes as its command: servo "
                                "(SERVO_OUTPUT_RAW), setpoint (NAV_CONTROLLER_OUTPUT: the "
                                "attitude error the autopilot is correcting), or auto (servo "
                                "outputs where the surface's channel is driven, else setpoints)",
                                choices=COMMAND_SOURCES)
    min_rate_hz: float = param(2.0, "control samples (a new command with a new body-rate "
                                "measurement) slower than this are not judged", positive=True)
    outputs: ServoMapConfig = section(ServoMapConfig, "servo output channels")
    model: ModelConfig = section(ModelConfig, "the per-axis models")
    fdi: AircraftFdiConfig = section(AircraftFdiConfig, "residual checks and isolation")


@dataclass(frozen=True, slots=True)
class ActuatorFamilyConfig:
    """Actuator and engine faults: the aircraft tier (from standard autopilot telemetry) and,
    where surface feedback exists, the servo tier (Lu2017)."""

    enabled: bool = param(True, "monitor the actuator family")
    servo: ServoTierConfig = section(ServoTierConfig, "servo tier: Lu2017 fault reconstruction "
                                     "per surface where SURF reports surface and rod positions")
    aircraft: AircraftTierConfig = section(AircraftTierConfig,
                                           "aircraft tier: surfaces and engine from servo "
                                           "outputs, setpoints and the aircraft's response")
