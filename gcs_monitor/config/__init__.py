"""Monitor configuration: TOML -> frozen dataclasses, validated once (docs/configuration.md)."""

from gcs_monitor.config.loader import (
    ConfigError,
    MonitorConfig,
    SinksConfig,
    TelemetryConfig,
    config_from_dict,
    config_markdown,
    config_toml,
    load_config,
)

__all__ = [
    "ConfigError", "MonitorConfig", "SinksConfig", "TelemetryConfig", "config_from_dict",
    "config_markdown", "config_toml", "load_config",
]
