"""Array aliases and channel identifiers shared by every layer."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

Vec = NDArray[np.float64]
Vec3 = NDArray[np.float64]
Mat = NDArray[np.float64]


@dataclass(frozen=True, slots=True, order=True)
class ChannelId:
    """A monitored channel: a sensor kind, its instance and (for vectors) an axis.

    kind examples: ``"aoa"``, ``"cas"``, ``"acc"``, ``"gyro"``, ``"actuator"``, ``"link"``.
    axis is ``""`` for scalar channels, else ``"x"``/``"y"``/``"z"`` or ``"p"``/``"q"``/``"r"``
    or a surface name.
    """

    kind: str
    instance: int = 0
    axis: str = ""
    # hash of (kind, instance, axis), computed once: channel ids key the per-sample dicts of
    # every Estimate, so the generated __hash__ (a tuple hash per lookup) showed in profiles
    _hash: int = field(init=False, repr=False, compare=False, default=0)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_hash", hash((self.kind, self.instance, self.axis)))

    def __hash__(self) -> int:
        return self._hash

    def __reduce__(self) -> tuple[type[ChannelId], tuple[str, int, str]]:
        # rebuilt through __init__: string hashes differ between processes (PYTHONHASHSEED)
        return (ChannelId, (self.kind, self.instance, self.axis))

    def __str__(self) -> str:
        base = f"{self.kind}{self.instance}"
        return f"{base}.{self.axis}" if self.axis else base
