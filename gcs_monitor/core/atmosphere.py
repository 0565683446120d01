"""International Standard Atmosphere (troposphere) and airspeed conversions.

The CAS conversion is Wan2018 eq. 16 (subsonic compressible pitot-static relation).
"""

from __future__ import annotations

import math
from typing import cast

from gcs_monitor.core import constants as c

_GAS_EXP = -c.GRAVITY_STD_MPS2 / (c.ISA_R_JPKGK * c.ISA_LAPSE_KPM)  # g / (-R L)


def isa_temperature_k(alt_m: float) -> float:
    """ISA temperature T = T0 + L z (Wan2018 eq. 16), z = pressure altitude in m."""
    return c.ISA_T0_K + c.ISA_LAPSE_KPM * alt_m


def isa_pressure_ratio(alt_m: float) -> float:
    """Static pressure over sea-level pressure, p_bar = (1 + L z / T0)^(-g/(R L))
    (Wan2018 eq. 16)."""
    return cast(float, (1.0 + c.ISA_LAPSE_KPM * alt_m / c.ISA_T0_K) ** _GAS_EXP)


def isa_pressure_pa(alt_m: float) -> float:
    """ISA static pressure at pressure altitude alt_m."""
    return c.ISA_P0_PA * isa_pressure_ratio(alt_m)


def isa_density_kgpm3(alt_m: float) -> float:
    """ISA density from the gas law."""
    return isa_pressure_pa(alt_m) / (c.ISA_R_JPKGK * isa_temperature_k(alt_m))


def cas_from_tas(tas_mps: float, alt_m: float, temp_k: float | None = None) -> float:
    """Calibrated airspeed from true airspeed (Wan2018 eq. 16).

    V_c = sqrt(5 gamma R T0) * rho(V_t, T, p_bar), with
    rho = sqrt([((1 + V_t^2/(5 gamma R T))^3.5 - 1) p_bar + 1]^(1/3.5) - 1).
    Wan2018 writes ``5 gamma R T``; the isentropic relation has ``(gamma-1)/2 = 1/5`` so
    ``V^2/(5 gamma R T)`` is ``(gamma-1)/2 * M^2`` -- consistent, kept as printed.
    """
    t = isa_temperature_k(alt_m) if temp_k is None else temp_k
    p_bar = isa_pressure_ratio(alt_m)
    k = 5.0 * c.ISA_GAMMA * c.ISA_R_JPKGK
    qc_over_p0 = ((1.0 + tas_mps * tas_mps / (k * t)) ** 3.5 - 1.0) * p_bar
    return math.sqrt(k * c.ISA_T0_K) * math.sqrt((qc_over_p0 + 1.0) ** (1.0 / 3.5) - 1.0)


def tas_from_cas(cas_mps: float, alt_m: float, temp_k: float | None = None) -> float:
    """Inverse of :func:`cas_from_tas` (closed form)."""
    t = isa_temperature_k(alt_m) if temp_k is None else temp_k
    p_bar = isa_pressure_ratio(alt_m)
    k = 5.0 * c.ISA_GAMMA * c.ISA_R_JPKGK
    qc_over_p0 = (1.0 + cas_mps * cas_mps / (k * c.ISA_T0_K)) ** 3.5 - 1.0
    return math.sqrt(k * t * ((qc_over_p0 / p_bar + 1.0) ** (1.0 / 3.5) - 1.0))


def impact_pressure_pa(cas_mps: float) -> float:
    """Impact (pitot minus static) pressure for a calibrated airspeed."""
    k = 5.0 * c.ISA_GAMMA * c.ISA_R_JPKGK
    return cast(float, c.ISA_P0_PA * ((1.0 + cas_mps * cas_mps / (k * c.ISA_T0_K)) ** 3.5 - 1.0))


def gravity_mps2(lat_rad: float, alt_m: float) -> float:
    """Gravity magnitude over the round earth (Lu2016 eq. 12)."""
    s = math.sin(lat_rad)
    s2 = math.sin(2.0 * lat_rad)
    ratio = c.EARTH_RADIUS_M / (c.EARTH_RADIUS_M + alt_m)
    return c.GRAVITY_EQUATOR_MPS2 * ratio * ratio * (1.0 + c.GRAVITY_LAT_K1 * s * s
                                                     - c.GRAVITY_LAT_K2 * s2 * s2)
