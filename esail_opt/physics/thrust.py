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
    """Radial and transverse thrust factors (Eqs. 3-4).

    Parameters
    ----------
    alpha : float or casadi expression
        Sail pitch angle alpha_n in radians, within [-pi/2, pi/2].
    coefficients : tuple of float
        (b1, b2).

    Returns
    -------
    R, T
        ``b1 + b2 cos(2 alpha)`` and ``b2 sin(2 alpha)``.
    """
    b1, b2 = coefficients
    return b1 + b2 * ca.cos(2 * alpha), b2 * ca.sin(2 * alpha)


def cone_angle(alpha, coefficients=EXACT):
    """Thrust cone angle atan(T / R) in radians: the thrust's tilt from the radial."""
    R, T = radial_transverse(alpha, coefficients)
    return ca.atan2(T, R)


def radial_transverse_normal(alpha, delta, coefficients=EXACT):
    """Thrust factors (R, T, N) in three dimensions, along r_hat, t_hat and h_hat.

    The sail's normal n lies at pitch ``alpha`` from r_hat and is turned by the clock
    angle ``delta`` about r_hat: delta = 0 keeps it in the orbital plane on the side of
    the motion (t_hat), positive delta turns it toward h_hat = r x v / |r x v|.  The
    solar wind is radial, so the sail's thrust is symmetric about r_hat: turning the
    normal by delta about r_hat turns the planar thrust (Eqs. 3-4) by delta about r_hat.
    Hence, for either coefficient set,

        (R, T, N) = (b1 + b2 cos 2 alpha, b2 sin 2 alpha cos delta, b2 sin 2 alpha sin delta),

    which is Eqs. 3-4 at delta = 0 (built from :func:`radial_transverse`, so the planar
    factors are these to the last bit).  With :data:`EXACT` it is Huo et al.'s
    a = (a_c/2)(r_E/r)[r_hat + (r_hat . n) n] (THEORY.md §9.1).

    Parameters
    ----------
    alpha, delta : float or casadi expression
        Pitch in [-pi/2, pi/2] and clock angle, radians.
    coefficients : tuple of float
        (b1, b2).
    """
    R, T = radial_transverse(alpha, coefficients)
    return R, T * ca.cos(delta), T * ca.sin(delta)


def canonical_attitude(alpha, delta):
    """The one of the two names of a sail attitude that a reader expects, radians.

    The sail's normal at (alpha, delta) and at (-alpha, delta + pi) is the same line (the
    normal is turned half a circle about r_hat and its pitch changes sign), so both give
    the same thrust.  The NLP may land on either name, a turn or two away.  The
    canonical name has delta in (-pi/2, pi/2]: the normal leans toward the side of the
    motion's half of the orbital plane, and a thrust that brakes shows as a negative
    pitch, as in the planar problem.
    """
    delta = math.remainder(delta, 2 * math.pi)  # in [-pi, pi]
    if delta <= -math.pi / 2 or delta > math.pi / 2:
        return -alpha, math.remainder(delta + math.pi, 2 * math.pi)
    return alpha, delta
