"""Evaluation: campaigns and paper experiments (uses sim_vehicle; see docs/architecture.md)."""
