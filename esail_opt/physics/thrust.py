"""The E-sail thrust model of Eqs. 3-4.

R and T are the radial and transverse components of the dimensionless propulsive
acceleration; the dimensional acceleration is ``a_c (r_E / r) (R, T)``.
"""

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
