"""Radial balance: the paper's Ref. [10] approximation (Quarta and Mengali, JGCD 36(3),
2013), r'' neglected in Eq. 1, used as a baseline (Sec. 3), derived from that assumption
alone for a constant attitude from a circular orbit of radius r0.

With mu = 1, r_E = 1 au, c = a_c r_E T and b = a_c r_E R: Eq. 2 gives h = h0 + c t
exactly; Eq. 1 without r'' gives h^2 = mu r - b r^2, whose root

    r(h) = 2 h^2 / (mu + S),   S = sqrt(mu^2 - 4 b h^2),

is free of the 0/0 of (mu - S) / (2 b) as a_c -> 0; v_theta = h / r, v_r = 2 h c / S and

    theta - theta0 = [mu/2 (1/r_i - 1/r) - b ln(r / r_i)] / c,   r_i = r(h0),

whose 0/0 as c -> 0 is removed by (r - r_i) / c = t (h + h0) / (mu - b (r + r_i)).

h0 = sqrt(mu r0), so h(t) is exact and r(0) = r(h0) is the centre about which the flown r
oscillates, not its bottom r0.  The model's initial state is therefore not the parking
orbit's: with a~_c = a_c r_E r0 / mu (Eq. 7) and v_c = sqrt(mu / r0), to first order,

* r(0) = r0 (1 + a~_c R)          (exactly 2 r0 / (1 + sqrt(1 - 4 a~_c R)));
* v_theta(0) = v_c (1 - a~_c R);
* v_r(0) = 2 a~_c T v_c            (exactly 2 h0 c / S(h0));
* theta(0) = theta0 and h(0) = h0 exactly.

The model exists while h > 0 and r <= mu / (2 b) (for T > 0, until
t = (mu / (2 sqrt(b)) - h0) / c); beyond it the square root returns NaN.
"""

import functools

import casadi as ca

MU = 1.0  # canonical gravitational parameter
R_E = 1.0  # reference distance of the characteristic acceleration, au

#: Below this |x| the series of log1p(x)/x serves; its 9 terms then err < 1e-19.
_SERIES_RADIUS = 0.01
_SERIES_TERMS = 9


def _log1p_over(x):
    """log1p(x) / x, finite with all derivatives at x = 0: the direct quotient is formed
    on a copy of x that the series branch replaces by a constant, since a 0/0 in the
    unused branch would still put NaN into derivatives."""
    small = ca.fabs(x) < _SERIES_RADIUS
    series = 0
    for n in range(_SERIES_TERMS - 1, -1, -1):
        series = series * (-x) + 1.0 / (n + 1)
    x_safe = ca.if_else(small, 0.5, x)
    return ca.if_else(small, series, ca.log1p(x_safe) / x_safe)


def radial_balance_state(t, r0, ac, R, T, theta0=0):
    """Polar state [r, theta, v_r, v_theta] (canonical) of Ref. [10]'s model at time
    ``t`` (TU) from a circular orbit of radius ``r0`` (au) at angle ``theta0`` (rad), with
    ``ac`` canonical (mu / au^2) and ``R``, ``T`` the constant factors of Eqs. 3-4.  At
    t = 0 it differs from the parking orbit by O(a~_c) (see the module docstring).
    """
    b, c = ac * R_E * R, ac * R_E * T
    h0 = ca.sqrt(MU * r0)
    h = h0 + c * t
    s = ca.sqrt(MU**2 - 4 * b * h**2)
    r = 2 * h**2 / (MU + s)
    r_i = 2 * h0**2 / (MU + ca.sqrt(MU**2 - 4 * b * h0**2))
    dr_over_c = t * (h + h0) / (MU - b * (r + r_i))
    x = c * dr_over_c / r_i
    theta = theta0 + dr_over_c * (MU / (2 * r * r_i) - b * _log1p_over(x) / r_i)
    return ca.vertcat(r, theta, 2 * h * c / s, h / r)


@functools.lru_cache(maxsize=None)
def radial_balance_function(samples):
    """:func:`radial_balance_state` over a row of times: ``(t[1 x samples], r0, ac, R, T,
    theta0) -> x[4 x samples]``."""
    t, r0, ac, R, T, theta0 = (ca.SX.sym(n) for n in ("t", "r0", "ac", "R", "T", "theta0"))
    point = ca.Function("radial_balance_point", [t, r0, ac, R, T, theta0],
                        [radial_balance_state(t, r0, ac, R, T, theta0)])
    return point.map("radial_balance", "serial", samples, [1, 2, 3, 4, 5], [])
