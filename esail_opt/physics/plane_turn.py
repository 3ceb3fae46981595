"""The orbital plane's turn over a closed-form arc (THEORY.md §9).

The plane's frame turns about r_hat at d(turn)/d(theta) = a~_c N / s^2 (s of Eq. 9;
``dynamics.rhs_turning``).  In the arc's frame (x along its first radius, z along h_hat,
angle phi from its start) the turn is the Magnus expansion

    Omega = Phi(phi) - (1/2) int_0^phi omega(p) x Phi(p) dp + O(a~_c^3),
    Phi(phi) = int_0^phi omega(p) dp,  omega = a~_c N / s^2 (cos phi, sin phi, 0).

At first order Phi is the closed-form integral I_b on the Keplerian s, error O(a~_c^2);
at second order s's drift and the commutator are added at the arc's Gauss-Legendre
nodes, error O(a~_c^3).  A turn is applied as quat_end = quat_start
exp(R_z(theta_start) Omega); the plane's theta is unchanged by it.
"""

import casadi as ca

from esail_opt.physics import rotation
from esail_opt.physics.closed_form import gauss_legendre
from esail_opt.physics.elements import s_of


def turn_rate(q, phi, actilde, N):
    """omega(phi) = a~_c N / s^2 (cos phi, sin phi, 0): the frame's rate of turn per
    radian, in the arc's frame, at elements q (``closed_form.FirstOrderArc``'s units)."""
    rate = actilde * N / s_of(q, phi) ** 2
    return ca.vertcat(rate * ca.cos(phi), rate * ca.sin(phi), 0)


def first_order_turn(arc, N, phi):
    """Phi(phi) = a~_c N h0^2 (Re I_b, Im I_b, 0): the turn's rotation vector at first
    order over ``arc`` (a ``closed_form.FirstOrderArc``), in the arc's frame."""
    i_b = arc.kepler.at(phi)[1]
    scale = arc.actilde * N * arc.h0**2
    return ca.vertcat(scale * i_b.re, scale * i_b.im, 0)


def second_order_turn(arc, N, phi, nodes):
    """The turn's rotation vector to second order in a~_c over [0, phi] of ``arc``: only
    the difference from the closed-form Phi, and the Magnus commutator, are integrated
    at the ``nodes`` Gauss-Legendre points."""
    xg, wg = gauss_legendre(nodes)
    eps = arc.actilde
    drift, commutator = 0, 0
    for xk, wk in zip(xg, wg):
        p = phi * xk
        omega0 = turn_rate(arc.q0, p, eps, N)
        drift = drift + wk * (turn_rate(arc.q(p), p, eps, N) - omega0)
        phi_k = first_order_turn(arc, N, p)
        commutator = commutator + wk * (omega0[0] * phi_k[1] - omega0[1] * phi_k[0])
    first = first_order_turn(arc, N, phi)
    return first + phi * drift - ca.vertcat(0, 0, 0.5 * phi * commutator)


def arc_turn(arc, N, phi, order=1, nodes=2):
    """The turn's rotation vector in the arc's frame over [0, phi], at ``order`` 1
    (:func:`first_order_turn`) or 2 (:func:`second_order_turn`)."""
    if order == 1:
        return first_order_turn(arc, N, phi)
    return second_order_turn(arc, N, phi, nodes)


def turned_plane(quat, theta_start, turn):
    """The plane's quaternion after an arc that started at the plane's angle
    ``theta_start`` and turned by ``turn`` (a rotation vector in the arc's frame)."""
    c, s = ca.cos(theta_start), ca.sin(theta_start)
    in_plane = ca.vertcat(c * turn[0] - s * turn[1], s * turn[0] + c * turn[1], turn[2])
    return rotation.multiply(quat, rotation.from_rotation_vector(in_plane))
