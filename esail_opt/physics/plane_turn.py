"""The orbital plane's turn over a closed-form arc (THEORY.md §9).

With the thrust f = f_R r_hat + f_T t_hat + f_N h_hat, the polar state obeys Eqs. 1-2
inside a plane whose frame turns about r_hat at the rate r f_N / h
(``dynamics.rhs_turning``).  With theta as the independent variable the rate is

    d(turn)/d(theta) = a~_c N / s^2  about r_hat(theta),

s of Eq. 9.  In the arc's frame (x along the arc's first radius, z along h_hat, angle
phi from the arc's start) the frame's orientation M(phi) obeys dM/dphi = M [omega(phi)]x
with omega = a~_c N / s^2 (cos phi, sin phi, 0), M(0) = 1.  Its Magnus expansion is

    M = exp([Omega]x),  Omega = Phi(phi) - (1/2) int_0^phi omega(p) x Phi(p) dp + O(a~_c^3),
    Phi(phi) = int_0^phi omega(p) dp.

* First order: s from the arc's Keplerian q0 (s0 = q3 w, w = 1 + e_x cos + e_y sin), so
  Phi = a~_c N h0^2 int_0^phi e^{ip} / w^2 dp, the integral I_b that the first-order arc
  already forms in closed form for every 0 <= e0 < 1 (``closed_form._KeplerIntegrals``);
  the error is O(a~_c^2), from s and from the commutator term, which is a turn about
  h_hat.
* Second order: the part of Phi that s's first-order drift adds, by the arc's
  Gauss-Legendre nodes on the first-order q (as ``closed_form.SecondOrderArc``), plus the
  commutator term on the first-order Phi at the same nodes; the error is O(a~_c^3).

A turn is applied to the plane's quaternion (``physics.rotation``'s convention) as
quat_end = quat_start exp(R_z(theta_start) Omega): the arc's frame is the plane's frame
turned by theta_start about z, and the plane's theta is unchanged by the turn.
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
    """Phi(phi) = a~_c N h0^2 (Re I_b, Im I_b, 0) on ``arc`` (a
    ``closed_form.FirstOrderArc``): the turn's rotation vector at first order, in the
    arc's frame, in closed form for every e0 (circular: a~_c N (sin phi, 1 - cos phi))."""
    i_b = arc.kepler.at(phi)[1]
    scale = arc.actilde * N * arc.h0**2
    return ca.vertcat(scale * i_b.re, scale * i_b.im, 0)


def second_order_turn(arc, N, phi, nodes):
    """The turn's rotation vector to second order in a~_c over [0, phi] of ``arc``.

    Phi with s on the first-order q(p) at the ``nodes`` Gauss-Legendre points of
    [0, phi] (only its difference from the closed-form Phi is integrated numerically),
    plus the Magnus commutator -(1/2) int omega x Phi, a turn about z, on the
    first-order omega and Phi at the same nodes.
    """
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
