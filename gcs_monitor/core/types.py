"""Array aliases and channel identifiers shared by every layer."""

from __future__ import annotations

from dataclasses import dataclass

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

    def __str__(self) -> str:
        base = f"{self.kind}{self.instance}"
        return f"{base}.{self.axis}" if self.axis else base
