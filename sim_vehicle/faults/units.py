"""Units accepted in scenario keys, per physical dimension, and their SI factors.

Config keys carry their unit as a suffix (``bias_deg``, ``rate_kts_per_s``); this table is the one
place that knows which suffixes exist and how to convert them to SI. Internally everything is SI
and radians (docs/style.md section 3).
"""

from __future__ import annotations

from gcs_monitor.core.units import DEG2RAD, FT2M, G2MPS2, HPA2PA, KT2MPS

# dimension -> {unit suffix: factor to SI}; the first entry is the SI unit of the dimension.
UNITS: dict[str, dict[str, float]] = {
    "acc": {"mps2": 1.0, "g": G2MPS2},
    "angrate": {"radps": 1.0, "degps": DEG2RAD},
    "angle": {"rad": 1.0, "deg": DEG2RAD},
    "speed": {"mps": 1.0, "kts": KT2MPS},
    "length": {"m": 1.0, "ft": FT2M},
    "pressure": {"pa": 1.0, "hpa": HPA2PA},
    # temperature *differences* (bias, amplitude): 1 K == 1 degC
    "temperature": {"k": 1.0, "degc": 1.0},
}

PER_S = "_per_s"


def si_unit(dimension: str) -> str:
    """The SI suffix of a dimension, e.g. ``"angle"`` -> ``"rad"``."""
    return next(iter(UNITS[dimension]))


def split_key(key: str, dimension: str) -> tuple[str, str, bool] | None:
    """Split ``<name>_<unit>[_per_s]`` into (name, unit, per_second) for a dimension.

    Returns None when the key does not end in a unit of that dimension.
    """
    per_s = key.endswith(PER_S)
    stem = key[: -len(PER_S)] if per_s else key
    for unit in sorted(UNITS[dimension], key=len, reverse=True):
        if stem.endswith("_" + unit):
            return stem[: -len(unit) - 1], unit, per_s
    return None


def accepted_suffixes(dimension: str, *, per_s: bool = False) -> list[str]:
    """Human-readable list of the accepted unit suffixes (for error messages)."""
    return [u + (PER_S if per_s else "") for u in UNITS[dimension]]
