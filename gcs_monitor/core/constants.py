"""The one home of physical constants. Every value cites its source."""

from __future__ import annotations

# Earth: Lu2016 sec. 2.1 uses a spherical earth, R_e = 6367 km, Omega = 7.2921e-5 rad/s.
EARTH_RADIUS_M = 6_367_000.0  # Lu2016 eq. 11
EARTH_RATE_RADPS = 7.2921e-5  # Lu2016 eq. 11
# Normal gravity at the equator and its latitude terms (Lu2016 eq. 12).
GRAVITY_EQUATOR_MPS2 = 9.780318
GRAVITY_LAT_K1 = 5.3024e-3
GRAVITY_LAT_K2 = 5.9e-6
GRAVITY_STD_MPS2 = 9.80665  # standard gravity (ISA, g-unit conversions)

# International Standard Atmosphere, troposphere (Wan2018 eq. 16 and ICAO Doc 7488).
ISA_T0_K = 288.15
ISA_P0_PA = 101_325.0
ISA_RHO0_KGPM3 = 1.225
ISA_LAPSE_KPM = -0.0065  # L = -6.5 K/km
ISA_R_JPKGK = 287.05287  # specific gas constant of dry air (Wan2018 eq. 16)
ISA_GAMMA = 1.4  # ratio of specific heats
ISA_TROPOPAUSE_M = 11_000.0
