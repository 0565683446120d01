"""Documented parameters: one place that says how a config field is written, read and shown.

Every parameter the monitor uses lives in a frozen dataclass next to the code that uses it and
is declared with :func:`param` (a scalar) or :func:`section` (a nested dataclass), so that one
function can print the whole default configuration with a comment per key
(``gcs-monitor config --defaults``) and ``docs/configuration.md`` is generated from it.

Fields are SI inside; the TOML key says its unit (style.md section 3). The key of a field is its
name with the SI suffix replaced by the display unit:

* by rule, angles are degrees in TOML: ``*_rad`` -> ``*_deg``, ``*_radps`` -> ``*_degps``,
  ``*_radps2`` -> ``*_degps2``, ``*_rad2`` -> ``*_deg2`` (a variance), ``*_rad2ps2`` ->
  ``*_deg2ps2``, ``*_rad_rs`` -> ``*_deg_rs`` (per square-root second);
* ``unit="kts"`` shows a speed in knots: ``*_mps`` -> ``*_kts``, ``*_mps2`` -> ``*_ktsps``;
* ``unit="si"`` keeps the SI key, for a value the paper gives in radians that has no decimal
  in degrees converting back to the same float (printed defaults must load back bit for bit);
* a field of a redundant-set or channel table whose unit depends on the set (a threshold in
  degrees for AoA, in knots for CAS) gives ``key="threshold_{u}"`` and takes the unit from the
  :func:`section` that holds the table (``section(..., unit=AOA_UNIT)``); ``{u}`` is the unit,
  ``{ur}`` its rate (per second).

``core`` holds this because models, filters, families and the simulator all declare parameters;
it does no I/O and imports no other project layer.
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, TypeVar

from gcs_monitor.core.units import DEG2RAD, KT2MPS

T = TypeVar("T")


@dataclass(frozen=True, slots=True)
class DisplayUnit:
    """A set-dependent display unit: ``name`` of the value, ``rate`` of its rate, SI factor."""

    name: str  # "deg"
    rate: str  # "degps"
    factor: float  # SI per display unit


DEG = DisplayUnit("deg", "degps", DEG2RAD)
KTS = DisplayUnit("kts", "ktsps", KT2MPS)
DEGPS = DisplayUnit("degps", "degps2", DEG2RAD)
MPS2 = DisplayUnit("mps2", "mps3", 1.0)
MPS = DisplayUnit("mps", "mps2", 1.0)
RAD = DisplayUnit("rad", "radps", 1.0)

# SI suffix -> (TOML suffix, SI per TOML unit); longest suffix first when matching
_ANGLE_SUFFIXES: dict[str, tuple[str, float]] = {
    "_rad2ps2": ("_deg2ps2", DEG2RAD * DEG2RAD),
    "_radps2": ("_degps2", DEG2RAD),
    "_rad_rs": ("_deg_rs", DEG2RAD),
    "_radps": ("_degps", DEG2RAD),
    "_rad2": ("_deg2", DEG2RAD * DEG2RAD),
    "_rad": ("_deg", DEG2RAD),
}
_KNOT_SUFFIXES: dict[str, tuple[str, float]] = {
    "_mps2": ("_ktsps", KT2MPS),
    "_mps": ("_kts", KT2MPS),
}


def param(default: T, doc: str, *, unit: str | None = None, key: str | None = None,
          choices: tuple[str, ...] | None = None, positive: bool = False,
          toml: bool = True, file: bool = False) -> T:
    """A documented scalar parameter (a dataclass field).

    Parameters
    ----------
    default : the default value, SI
    doc : one line for the configuration page and ``config --defaults``
    unit : ``"kts"`` to show an SI speed in knots (see the module docstring); ``"si"`` keeps
        the SI key (a paper value given in radians that has no exact decimal in degrees)
    key : TOML key template for set-dependent units (``"threshold_{u}"``)
    choices : allowed values of a string parameter
    positive : a number that must be > 0 (otherwise >= 0)
    toml : False for a field the configuration file does not set (filled in by its owner)
    file : a string that may name a file (one with a suffix); a relative one is relative to
        the folder of the configuration file that sets it
    """
    md = {"doc": doc, "unit": unit, "key": key, "choices": choices, "positive": positive,
          "toml": toml, "file": file}
    return dataclasses.field(default=default, metadata=md)


def section(factory: Callable[[], T], doc: str, *, unit: DisplayUnit | None = None) -> T:
    """A documented nested table (a dataclass field built by ``factory``); ``unit`` is the
    display unit of the ``{u}`` keys inside it."""
    return dataclasses.field(
        default_factory=factory, metadata={"doc": doc, "set_unit": unit, "toml": True})


@dataclass(frozen=True, slots=True)
class KeySpec:
    """How one dataclass field appears in TOML."""

    field: str  # dataclass field name
    key: str  # TOML key
    factor: float  # SI per TOML unit (1.0 for non-numbers)
    doc: str
    choices: tuple[str, ...] | None
    positive: bool


def _doc_from_docstring(cls: type, name: str) -> str:
    """The numpydoc ``Attributes`` entry of ``name`` in ``cls``'s docstring (for dataclasses
    declared without :func:`param`), or ``""``."""
    doc = cls.__doc__ or ""
    m = re.search(rf"^\s*{re.escape(name)}\b[^:\n]*:\s*(.*(?:\n\s{{8,}}\S.*)*)", doc, re.M)
    if m is None:
        pattern = rf"^\s*(?:\w+,\s*)*{re.escape(name)}(?:,\s*\w+)*\s*:\s*(.*(?:\n\s{{8,}}\S.*)*)"
        m = re.search(pattern, doc, re.M)
    return " ".join(m.group(1).split()) if m else ""


def key_spec(cls: type, f: dataclasses.Field[Any], set_unit: DisplayUnit | None) -> KeySpec:
    """The TOML face of field ``f`` of dataclass ``cls`` inside a table of unit ``set_unit``."""
    md = f.metadata
    doc = md.get("doc") or _doc_from_docstring(cls, f.name)
    tmpl = md.get("key")
    if tmpl:
        if set_unit is None:
            raise TypeError(f"{cls.__name__}.{f.name}: key {tmpl!r} needs a section unit")
        factor = set_unit.factor if "{u}" in tmpl or "{ur}" in tmpl else 1.0
        return KeySpec(f.name, tmpl.format(u=set_unit.name, ur=set_unit.rate), factor, doc,
                       md.get("choices"), bool(md.get("positive")))
    if md.get("unit") == "si":
        return KeySpec(f.name, f.name, 1.0, doc, md.get("choices"), bool(md.get("positive")))
    table = _KNOT_SUFFIXES if md.get("unit") == "kts" else _ANGLE_SUFFIXES
    for si, (shown, factor) in table.items():
        if f.name.endswith(si):
            return KeySpec(f.name, f.name[: -len(si)] + shown, factor, doc, md.get("choices"),
                           bool(md.get("positive")))
    return KeySpec(f.name, f.name, 1.0, doc, md.get("choices"), bool(md.get("positive")))


def in_toml(f: dataclasses.Field[Any]) -> bool:
    """Whether the configuration file sets this field."""
    return bool(f.metadata.get("toml", True))


def display(value: float, factor: float) -> float:
    """An SI value in its TOML unit, rounded to the shortest decimal that converts back to the
    same SI float when one exists (so printed defaults load back bit for bit)."""
    if factor == 1.0 or not math.isfinite(value):
        return value
    shown = value / factor
    for digits in range(1, 18):
        candidate = float(f"{shown:.{digits}g}")
        if candidate * factor == value:
            return candidate
    return shown
