"""Radial balance: the paper's Ref. [10] approximation, r'' neglected in Eq. 1, used as
a baseline (Sec. 3).

The module is named for what it models: with r'' = 0 gravity, the centrifugal term and
the radial thrust balance at every instant, so the orbit stays quasi-circular.

Quarta and Mengali (JGCD 36(3), 2013) approximate a low-acceleration E-sail with
constant attitude leaving a circular orbit of radius r0, in 2-D.  Only their
assumption is available here (Sec. 3 of the paper): the radial acceleration r''
is neglected in Eq. 1.  The model below is derived from that assumption alone.

Derivation (canonical units, mu = 1, r_E = 1 au; c = a_c r_E T, b = a_c r_E R)
---------------------------------------------------------------------------
* Eq. 2 is d(r v_theta)/dt = a_c r_E T, so h = h0 + c t, exactly.
* Eq. 1 without r'' is -h^2 / r^3 = -mu / r^2 + b / r, i.e. h^2 = mu r - b r^2,
  whose root through r = h^2 / mu at b = 0 is

      r(h) = 2 h^2 / (mu + S),   S = sqrt(mu^2 - 4 b h^2),

  free of the 0/0 that the textbook form (mu - S) / (2 b) has as a_c -> 0.
* v_theta = h / r and v_r = (dr/dh) c = 2 h c / S (from 2 h dh = (mu - 2 b r) dr
  and mu - 2 b r = S).
* theta' = h / r^2 and dh = c dt give dtheta = (h / r^2) dh / c, and along r(h)
  (h / r^2) dh = dF with F(r) = -mu / (2 r) - b ln r, so

      theta - theta0 = [mu/2 (1/r_i - 1/r) - b ln(r / r_i)] / c,   r_i = r(h0).

  This is 0/0 as c -> 0.  With h^2 - h0^2 = (r - r_i)(mu - b (r + r_i)) and
  h^2 - h0^2 = c t (h + h0), the ratio (r - r_i) / c = t (h + h0) / (mu - b (r + r_i))
  has no division by c, and what is left is log1p(x) / x with x = (r - r_i) / r_i,
  evaluated by a series near x = 0.

Initial condition
-----------------
h0 = sqrt(mu r0), the parking orbit's angular momentum.  Then h(t) is the exact
h(t) of Eqs. 1-2 at every t, and r(0) = r(h0) is the circular orbit balanced by
gravity minus the radial thrust: the centre about which the flown r oscillates.
(Choosing r(0) = r0 instead would put the model at the bottom of that oscillation.)
The price is that the model's initial state is not the parking orbit's.  With
a~_c = a_c r_E r0 / mu (Eq. 7) and v_c = sqrt(mu / r0), to first order in a~_c:

* r(0) = r0 (1 + a~_c R)          (exactly 2 r0 / (1 + sqrt(1 - 4 a~_c R)));
* v_theta(0) = v_c (1 - a~_c R);
* v_r(0) = 2 a~_c T v_c            (exactly 2 h0 c / S(h0));
* theta(0) = theta0 and h(0) = h0 exactly.

On the paper's case (a_c = 0.1 mm/s^2, alpha = 45 deg, r0 = 1 au) a~_c R = 1.26 %.

Validity: the model exists while h > 0 and 4 b h^2 <= mu^2, that is r <= mu / (2 b)
(for T > 0, until t = (mu / (2 sqrt(b)) - h0) / c; about 130 years on the paper's
case).  Beyond it the square root returns NaN.
"""

import functools

import casadi as ca

MU = 1.0  # canonical gravitational parameter
R_E = 1.0  # reference distance of the characteristic acceleration, au

#: Below this |x| the series of log1p(x)/x serves; its 9 terms then err < 1e-19.
_SERIES_RADIUS = 0.01
_SERIES_TERMS = 9


def _log1p_over(x):
    """log1p(x) / x, finite with all derivatives at x = 0.

    The direct quotient is formed on a copy of x that the series branch replaces by a
    harmless constant: if_else evaluates both branches, and a 0/0 in the unused one
    would still put NaN into derivatives.
    """
    small = ca.fabs(x) < _SERIES_RADIUS
    series = 0
    for n in range(_SERIES_TERMS - 1, -1, -1):
        series = series * (-x) + 1.0 / (n + 1)
    x_safe = ca.if_else(small, 0.5, x)
    return ca.if_else(small, series, ca.log1p(x_safe) / x_safe)


def radial_balance_state(t, r0, ac, R, T, theta0=0):
    """Polar state of Ref. [10]'s model (Eqs. 1-2 with r'' = 0) at time t.

    Parameters
    ----------
    t : scalar
        Time since departure, TU.
    r0 : scalar
        Radius of the circular parking orbit, au.
    ac : scalar
        Characteristic acceleration at r_E = 1 au, canonical units (mu / au^2).
    R, T : scalars
        Thrust factors of Eqs. 3-4, constant along the trajectory.
    theta0 : scalar
        Polar angle at t = 0, rad.

    Returns
    -------
    casadi 4-vector
        [r, theta, v_r, v_theta], canonical units.  At t = 0 it differs from the
        parking orbit by O(a~_c); see the module docstring.
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
    """Compiled :func:`radial_balance_state` over a row of ``samples`` times.

    Returns a ``casadi.Function`` ``(t[1 x samples], r0, ac, R, T, theta0) ->
    x[4 x samples]``; the scalar arguments are shared by all times.
    """
    t, r0, ac, R, T, theta0 = (ca.SX.sym(n) for n in ("t", "r0", "ac", "R", "T", "theta0"))
    point = ca.Function("radial_balance_point", [t, r0, ac, R, T, theta0],
                        [radial_balance_state(t, r0, ac, R, T, theta0)])
    return point.map("radial_balance", "serial", samples, [1, 2, 3, 4, 5], [])
