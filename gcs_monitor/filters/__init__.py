"""Model-agnostic estimation algorithms (no aircraft knowledge)."""
