"""Converters from real flight-data formats to .tlog files that follow docs/telemetry.md."""
