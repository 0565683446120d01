"""Conversion factors. Non-SI values exist only at the boundaries (MAVLink, config, display)."""

from __future__ import annotations

import math

DEG2RAD = math.pi / 180.0
RAD2DEG = 180.0 / math.pi
KT2MPS = 1852.0 / 3600.0
MPS2KT = 3600.0 / 1852.0
FT2M = 0.3048
M2FT = 1.0 / 0.3048
FPM2MPS = 0.3048 / 60.0
HPA2PA = 100.0
PA2HPA = 0.01
G2MPS2 = 9.80665
DEGE7_2RAD = 1.0e-7 * DEG2RAD
RAD2DEGE7 = RAD2DEG * 1.0e7
CM2M = 0.01
MM2M = 0.001
US2S = 1.0e-6
S2US = 1_000_000
MS2US = 1_000
