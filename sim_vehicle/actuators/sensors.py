"""The servo position sensors as the SURF message reports them (Lu2017 eq. 3: ``y_m = y + v``).

Per surface the rod position sensor (``rod_pos_m``, after the liquid-jam bias of Lu2017 eq. 5)
and the surface position sensor (``surf_pos_rad``) each add white noise; the commanded
deflection goes out as commanded. Lu2017 has a measurement noise ``v`` but gives no value; the
1-sigma values below are ours: a rod LVDT reading to 0.1 mm (0.03 % of the transport's
0.35 m stroke) and a surface RVDT to 0.05 deg.

The noise has its own generator (seeded from the scenario seed and a fixed stream number), so
it leaves every other random stream of a run -- turbulence, the sensor suite -- as it was.
The true state (and the truth recorder) keeps the noise-free values.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from gcs_monitor.core.units import DEG2RAD
from sim_vehicle.state import TrueState

SURF_NOISE_STREAM = 0x5E12F0  # second seed word of the SURF noise generator


@dataclass(frozen=True, slots=True)
class SurfaceSensorNoise:
    """1-sigma white noise of the servo position sensors (ours; Lu2017 gives no value)."""

    rod_sigma_m: float = 1.0e-4
    surf_sigma_rad: float = 0.05 * DEG2RAD


class SurfaceSensors:
    """Adds the sensor noise to the true state's surface and rod positions for the SURF message.
    """

    def __init__(self, noise: SurfaceSensorNoise, seed: int) -> None:
        self.noise = noise
        self._rng = np.random.default_rng([seed, SURF_NOISE_STREAM])

    def measure(self, st: TrueState) -> TrueState:
        """``st`` with noisy ``surf_pos_rad`` and ``rod_pos_m`` (one draw per call)."""
        n = self.noise
        e = self._rng.standard_normal(6)
        return dataclasses.replace(st, surf_pos_rad=st.surf_pos_rad + n.surf_sigma_rad * e[:3],
                                   rod_pos_m=st.rod_pos_m + n.rod_sigma_m * e[3:])
