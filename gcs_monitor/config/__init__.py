"""Monitor configuration: TOML -> frozen dataclasses, validated once (see defaults.toml)."""

from gcs_monitor.config.loader import (
    AirDataConfig,
    ConfigError,
    EstimatorsConfig,
    FdiConfig,
    MonitorConfig,
    SetConfig,
    SinksConfig,
    TelemetryConfig,
    load_config,
    scheduled_threshold,
)

__all__ = [
    "AirDataConfig", "ConfigError", "EstimatorsConfig", "FdiConfig", "MonitorConfig", "SetConfig",
    "SinksConfig", "TelemetryConfig", "load_config", "scheduled_threshold",
]
