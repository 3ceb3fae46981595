"""Physical constants and the package's only unit conversions.

Inside, lengths are in au, mu_sun = 1, time in TU = sqrt(au^3 / mu_sun) (about 58.13 days)
and angles in radians; the boundary (problem files, CLI, JSON, plots) speaks au, days,
degrees, km/s and mm/s^2."""

import math

MU_SUN = 1.32712440018e20  # m^3/s^2
AU = 1.495978707e11  # m
DAY = 86400.0  # s
YEAR_DAYS = 365.25

TU_SECONDS = math.sqrt(AU**3 / MU_SUN)
TU_DAYS = TU_SECONDS / DAY
VU_KM_S = AU / TU_SECONDS / 1e3
#: mu_sun / au^2, the Sun's gravity at 1 au: the canonical unit of acceleration.
ACC_UNIT_MM_S2 = MU_SUN / AU**2 * 1e3


def accel_from_mm_s2(a_mm_s2):
    """Characteristic acceleration from mm/s^2 to canonical units (mu/au^2)."""
    return a_mm_s2 / ACC_UNIT_MM_S2


def time_from_days(t_days):
    return t_days / TU_DAYS


def time_to_days(t):
    return t * TU_DAYS


def time_from_years(years):
    return years * YEAR_DAYS / TU_DAYS


def speed_to_km_s(v):
    return v * VU_KM_S


def speed_to_m_s(v):
    return v * VU_KM_S * 1e3


def speed_from_km_s(v_km_s):
    return v_km_s / VU_KM_S


def length_to_km(r):
    return r * AU / 1e3
