"""The E-sail thrust model of Eqs. 3-4.

R and T are the radial and transverse components of the dimensionless propulsive
acceleration; the dimensional acceleration is ``a_c (r_E / r) (R, T)``.
"""

import math

import casadi as ca

#: Huo et al.'s geometric model: Eqs. 3-4 are exact with these coefficients.
EXACT = (0.75, 0.25)
#: The older best fit to Yamaguchi and Yamakawa's data quoted with Eq. 3.
BEST_FIT = (0.7477, 0.2523)


def radial_transverse(alpha, coefficients=EXACT):
    """Radial and transverse thrust factors (Eqs. 3-4), ``b1 + b2 cos(2 alpha)`` and
    ``b2 sin(2 alpha)``, of the pitch alpha_n (rad, in [-pi/2, pi/2], float or CasADi)
    and ``coefficients`` (b1, b2)."""
    b1, b2 = coefficients
    return b1 + b2 * ca.cos(2 * alpha), b2 * ca.sin(2 * alpha)


def cone_angle(alpha, coefficients=EXACT):
    """Thrust cone angle atan(T / R) in radians: the thrust's tilt from the radial."""
    R, T = radial_transverse(alpha, coefficients)
    return ca.atan2(T, R)


def radial_transverse_normal(alpha, delta, coefficients=EXACT):
    """Thrust factors (R, T, N) in three dimensions, along r_hat, t_hat and h_hat.

    The sail's normal lies at pitch ``alpha`` (rad, in [-pi/2, pi/2]) from r_hat, turned
    by the clock angle ``delta`` (rad) about r_hat: delta = 0 keeps it in the orbital
    plane on the side of the motion, positive delta turns it toward h_hat.  The solar
    wind is radial, so the planar thrust (Eqs. 3-4) turns by delta with it:

        (R, T, N) = (b1 + b2 cos 2 alpha, b2 sin 2 alpha cos delta, b2 sin 2 alpha sin delta),

    at delta = 0 :func:`radial_transverse`'s to the last bit.  With :data:`EXACT` it is
    Huo et al.'s a = (a_c/2)(r_E/r)[r_hat + (r_hat . n) n] (THEORY.md §9.1).
    """
    R, T = radial_transverse(alpha, coefficients)
    return R, T * ca.cos(delta), T * ca.sin(delta)


def canonical_attitude(alpha, delta):
    """The one of the two names of a sail attitude that a reader expects, radians.

    (alpha, delta) and (-alpha, delta + pi) are the same normal line, so the same thrust,
    and the NLP may land on either, a turn or two away.  The canonical name has delta in
    (-pi/2, pi/2], so that a thrust that brakes shows as a negative pitch, as in the
    planar problem.
    """
    delta = math.remainder(delta, 2 * math.pi)  # in [-pi, pi]
    if delta <= -math.pi / 2 or delta > math.pi / 2:
        return -alpha, math.remainder(delta + math.pi, 2 * math.pi)
    return alpha, delta
