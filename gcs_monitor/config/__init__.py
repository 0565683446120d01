"""Monitor configuration: TOML -> frozen dataclasses, validated once (see defaults.toml)."""

from gcs_monitor.config.loader import (
    ConfigError,
    EstimatorsConfig,
    FdiConfig,
    MonitorConfig,
    SetConfig,
    SinksConfig,
    TelemetryConfig,
    load_config,
)

__all__ = [
    "ConfigError", "EstimatorsConfig", "FdiConfig", "MonitorConfig", "SetConfig", "SinksConfig",
    "TelemetryConfig", "load_config",
]
