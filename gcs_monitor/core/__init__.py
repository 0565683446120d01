"""Shared, stateless foundations: constants, units, frames, atmosphere, types (numpy/scipy only)."""
