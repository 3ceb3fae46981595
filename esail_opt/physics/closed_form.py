"""The paper's first-order closed form of a fixed-attitude arc (Eqs. 12-26).

Not Eqs. 15 and 20-26 as printed: they measure theta from the parking orbit's apse line
and carry 1/e0 factors, a pole in tan(theta/2) and a branch jump in E (Eq. 26), which lose
every digit on the nearly circular orbits an optimiser restarts arcs on.  Here Eq. 13 is
integrated in a frame whose theta starts at the arc's first radius (so the eccentricity
vector (e_x, e_y) is smooth in the state), with the complex variable

    u(phi) = beta e^{-i omega} e^{i phi},   beta = e / (1 + sqrt(1 - e^2)).

Since |u| < 1, the principal log(1 + u) is continuous over any number of revolutions,
E - f = -2 arg(1 + u), and the one removable singularity left, log(1 + u) / u, is
evaluated by a series near u = 0.  The result equals Eq. 15 at e0 = 0 and Eqs. 20-26 for
e0 > 0, with finite first and second derivatives on all of 0 <= e0 < 1.

Lengths are in r0 (the arc's first radius), speeds in sqrt(mu / r0), as in the paper;
:func:`arc_end` converts from and to the canonical polar state.  Eq. 6 as printed carries
1/(q3 s^2); the consistent prefactor is 1/s^2 (THEORY.md §2.3, §6.1), which Eq. 14, the
only one used here, agrees with.
"""

import casadi as ca
import numpy as np

from esail_opt.physics.elements import ac_tilde, polar_from_q, q_from_polar, s_of


class _Complex:
    """A complex number whose parts are CasADi expressions or floats."""

    __slots__ = ("re", "im")

    def __init__(self, re, im=0.0):
        self.re, self.im = re, im

    @staticmethod
    def _lift(z):
        return z if isinstance(z, _Complex) else _Complex(z, 0.0)

    def __add__(self, other):
        other = self._lift(other)
        return _Complex(self.re + other.re, self.im + other.im)

    __radd__ = __add__

    def __sub__(self, other):
        other = self._lift(other)
        return _Complex(self.re - other.re, self.im - other.im)

    def __rsub__(self, other):
        return self._lift(other) - self

    def __neg__(self):
        return _Complex(-self.re, -self.im)

    def __mul__(self, other):
        other = self._lift(other)
        return _Complex(
            self.re * other.re - self.im * other.im,
            self.re * other.im + self.im * other.re,
        )

    __rmul__ = __mul__

    def __truediv__(self, other):
        other = self._lift(other)
        den = other.re**2 + other.im**2
        return _Complex(
            (self.re * other.re + self.im * other.im) / den,
            (self.im * other.re - self.re * other.im) / den,
        )

    def __rtruediv__(self, other):
        return self._lift(other) / self

    def conj(self):
        return _Complex(self.re, -self.im)

    def abs2(self):
        return self.re**2 + self.im**2


_I = _Complex(0.0, 1.0)


def _expi(phi):
    return _Complex(ca.cos(phi), ca.sin(phi))


def _log1p_right_half(u):
    """Principal log(1 + u) for Re(1 + u) > 0, where arg(1 + u) is an atan."""
    one_plus = 1 + u
    return _Complex(0.5 * ca.log(one_plus.abs2()), ca.atan(one_plus.im / one_plus.re))


#: Below this |u| the series serves; above it the direct quotient loses < 1 digit.
_SERIES_RADIUS = 0.3
#: atanh(v)/v = sum v^(2n)/(2n+1); with |v| <= 0.3/1.7 the 13th term is below 1e-19.
_SERIES_TERMS = 13


def _log1p_over(u, small, log1p_u):
    """log(1 + u) / u for |u| < 1, finite with all derivatives at u = 0.

    ``small`` is the (scalar) condition |u| < _SERIES_RADIUS, where the series of
    2 atanh(v) / u, v = u / (2 + u), serves; ``log1p_u`` is log(1 + u), passed in because
    an arc's cost is mostly its complex logarithms.  The direct quotient divides by a copy
    of u that the series branch replaces by a constant: a 0/0 in the unselected branch
    would still put NaN into derivatives.
    """
    v = u / (2 + u)
    v2 = v * v
    series = _Complex(1.0 / (2 * _SERIES_TERMS - 1), 0.0)
    for n in range(_SERIES_TERMS - 2, -1, -1):
        series = series * v2 + 1.0 / (2 * n + 1)
    series = series * (2 / (2 + u))
    u_safe = _Complex(ca.if_else(small, 0.5, u.re), ca.if_else(small, 0.0, u.im))
    direct = log1p_u / u_safe
    return _Complex(
        ca.if_else(small, series.re, direct.re), ca.if_else(small, series.im, direct.im)
    )


class _KeplerIntegrals:
    """Integrals over [0, phi] along the Keplerian orbit w = 1 + e_x cos + e_y sin, the
    arc's constants formed once for all phi.  ``at(phi)`` returns (I_a, I_b, I_c):
    int e^{i phi}/w, int e^{i phi}/w^2 and int 1/w^2 = (Delta M)/(1 - e^2)^{3/2}.
    """

    def __init__(self, ex, ey):
        self.ex, self.ey = ex, ey
        self.e2 = ex**2 + ey**2
        self.root = ca.sqrt(1 - self.e2)
        b = 1 / (1 + self.root)
        self.kappa = _Complex(b * ex, -b * ey)  # u at phi = 0
        self.small = b**2 * self.e2 < _SERIES_RADIUS**2
        self.log0 = _log1p_right_half(self.kappa)
        self.lam0 = _log1p_over(self.kappa, self.small, self.log0)
        self.w0 = 1 + ex
        self.esin0 = -ey / self.w0  # e sin(f) / w at phi = 0

    def w(self, phi):
        return 1 + self.ex * ca.cos(phi) + self.ey * ca.sin(phi)

    def i_c(self, phi, rot=None, dlog=None):
        """int_0^phi dphi / w^2, from Kepler's equation with E - f = -2 arg(1 + u)."""
        rot = _expi(phi) if rot is None else rot
        dlog = _log1p_right_half(self.kappa * rot) - self.log0 if dlog is None else dlog
        w1 = 1 + self.ex * rot.re + self.ey * rot.im
        # The change of e sin(f) / w turns Delta E into Delta M.
        desin = (self.ex * rot.im - self.ey * rot.re) / w1 - self.esin0
        one_m_e2 = 1 - self.e2
        return (phi - 2 * dlog.im) / (self.root * one_m_e2) - desin / one_m_e2

    def at(self, phi):
        rot = _expi(phi)
        u = self.kappa * rot
        log1p_u = _log1p_right_half(u)
        dlog = log1p_u - self.log0
        lam = _log1p_over(u, self.small, log1p_u)
        i_a = (
            -_I * (rot * lam - self.lam0) - self.kappa.conj() * (phi - _I * dlog.conj())
        ) / self.root
        i_c = self.i_c(phi, rot, dlog)
        w1 = 1 + self.ex * rot.re + self.ey * rot.im
        i_b = -_I * (rot / w1 - 1 / self.w0) - _Complex(self.ex, self.ey) * i_c
        return i_a, i_b, i_c


class FirstOrderArc:
    """The first-order solution of one fixed-attitude arc (Eq. 12), in the arc's frame.

    ``q0`` are the elements (Eq. 5) at phi = 0, theta 0 at the arc's start and normalised
    by the radius there (q0_3 s(0) = 1); ``actilde`` is a~_c of Eq. 7 (times any
    throttle), ``R``, ``T`` the thrust factors of Eqs. 3-4.
    """

    def __init__(self, q0, actilde, R, T):
        self.q0 = q0
        self.h0 = 1 / q0[2]
        self.kepler = _KeplerIntegrals(q0[0] * self.h0, q0[1] * self.h0)
        self.actilde, self.R, self.T = actilde, R, T

    def matrix(self, phi):
        """D(phi) with q(phi) = q0 + a~_c D(phi) [R, T]^T: h0 * int_0^phi B (Eq. 14)."""
        i_a, i_b, i_c = self.kepler.at(phi)
        return self.h0 * ca.vertcat(
            ca.horzcat(i_a.im, i_a.re + i_b.re),
            ca.horzcat(-i_a.re, i_a.im + i_b.im),
            ca.horzcat(0, -i_c),
        )

    def q(self, phi):
        """q(phi) = q0 + a~_c D(phi) [R, T]^T (Eqs. 12, 13; Eqs. 15-16 at e0 = 0)."""
        return self.q0 + self.actilde * ca.mtimes(self.matrix(phi), ca.vertcat(self.R, self.T))

    def clock_rate(self, phi):
        """dt/dphi on the first-order q (:func:`clock_rate`)."""
        return clock_rate(self.q(phi), phi)

    def time(self, phi_a, phi_b, nodes=8):
        """Time from phi_a to phi_b, in units sqrt(r0^3 / mu): the Keplerian part of
        dt/dphi exactly (Kepler's equation), the first-order remainder, of relative size
        a~_c, by a ``nodes``-point Gauss-Legendre rule."""
        kep = self.kepler
        exact = self.h0**3 * (kep.i_c(phi_b) - kep.i_c(phi_a))
        xg, wg = gauss_legendre(nodes)
        width = phi_b - phi_a
        correction = 0
        for xk, wk in zip(xg, wg):
            phi = phi_a + width * xk
            correction += wk * (self.clock_rate(phi) - self.h0**3 / kep.w(phi) ** 2)
        return exact + width * correction


def clock_rate(q, phi):
    """dt/dphi = 1 / (q3 s^2) at elements q, in units sqrt(r0^3 / mu)
    (:func:`~esail_opt.physics.elements.s_of`; Eq. 9: r = 1 / (q3 s))."""
    return 1 / (q[2] * s_of(q, phi) ** 2)


def element_rate(q, phi, R, T):
    """dq/dtheta per unit a~_c on the exact motion (THEORY.md §2.3): (1/s^2) A [R, T]^T,
    with s of Eq. 9 (:func:`~esail_opt.physics.elements.s_of`) and elements, angle and
    lengths as in :class:`FirstOrderArc`."""
    c, s_phi = ca.cos(phi), ca.sin(phi)
    s = s_of(q, phi)
    return ca.vertcat(s * s_phi * R + (s + q[2]) * c * T,
                      -s * c * R + (s + q[2]) * s_phi * T,
                      -q[2] * T) / s**2


def _node_integrals(nodes):
    """W[k, j] = int_0^{x_k} L_j(x) dx on [0, 1], L_j the Lagrange polynomials through 0
    and the Gauss-Legendre nodes x_k, j over the nodes only: integrates a function that
    vanishes at 0, known at the nodes, from 0 to each node."""
    xg, _ = gauss_legendre(nodes)
    points = np.r_[0.0, xg]
    weights = np.zeros((nodes, nodes))
    for j in range(nodes):
        basis = np.poly1d([1.0])
        for m, pm in enumerate(points):
            if m != j + 1:
                basis = basis * np.poly1d([1.0, -pm]) / (points[j + 1] - pm)
        primitive = basis.integ()
        weights[:, j] = primitive(xg) - primitive(0.0)
    return weights


class SecondOrderArc:
    """One Picard sweep on :class:`FirstOrderArc`: the arc to second order in a~_c.

    The right side of dq/dtheta, which Eq. 12 freezes at q0, is evaluated on the
    first-order q at the Gauss-Legendre nodes of [0, phi], and only its difference from
    the frozen one is integrated numerically:

        q(phi) = q_1(phi) + a~_c phi sum_k w_k [F(q_1(phi_k), phi_k) - F(q0, phi_k)].

    The error left is O(a~_c^3 phi^3) plus the quadrature's (THEORY.md §3.8).  The clock's
    q at its nodes is brought to second order the same way (:func:`_node_integrals`).
    """

    def __init__(self, arc, phi, nodes):
        xg, wg = gauss_legendre(nodes)
        phis = [phi * x for x in xg]
        q0, eps, R, T = arc.q0, arc.actilde, arc.R, arc.T
        firsts = [arc.q(p) for p in phis]
        excess = [eps * (element_rate(q, p, R, T) - element_rate(q0, p, R, T))
                  for q, p in zip(firsts, phis)]
        #: The first-order elements at phi (whose q3 is the arc's validity margin), and
        #: the second-order ones.
        self.q_first = arc.q(phi)
        self.q_end = self.q_first + phi * sum(w * d for w, d in zip(wg, excess))
        weights = _node_integrals(nodes)
        at_nodes = [q + phi * sum(weights[k, j] * excess[j] for j in range(nodes))
                    for k, q in enumerate(firsts)]
        kep = arc.kepler
        exact = arc.h0**3 * kep.i_c(phi)  # i_c(0) = 0
        rates = [clock_rate(q, p) - arc.h0**3 / kep.w(p) ** 2
                 for q, p in zip(at_nodes, phis)]
        #: Time from 0 to phi, in units sqrt(r0^3 / mu).
        self.time = exact + phi * sum(w * r for w, r in zip(wg, rates))


def q_of_theta(q0, theta0, theta, actilde, R, T):
    """First-order elements q(theta) of Eq. 12 in any fixed reference frame, from the
    elements ``q0`` at ``theta0`` normalised by r(theta0) (the paper's parking orbit:
    Eq. 8, theta from the apse line)."""
    c0, s0 = ca.cos(theta0), ca.sin(theta0)
    # Rotating the reference direction by theta0 rotates (q1, q2) by -theta0.
    q_local = ca.vertcat(c0 * q0[0] + s0 * q0[1], -s0 * q0[0] + c0 * q0[1], q0[2])
    q = FirstOrderArc(q_local, actilde, R, T).q(theta - theta0)
    return ca.vertcat(c0 * q[0] - s0 * q[1], s0 * q[0] + c0 * q[1], q[2])


def theta_max_circular(actilde, T):
    """Largest arc angle with q3 > 0 from a circular orbit: 1 / (T a~_c) (after Eq. 16)."""
    return 1 / (T * actilde)


def gauss_legendre(nodes):
    """Nodes and weights of the n-point Gauss-Legendre rule on [0, 1]."""
    x, w = np.polynomial.legendre.leggauss(nodes)
    return (x + 1) / 2, w / 2


def arc_frame(x0, ac, R, T):
    """The :class:`FirstOrderArc` that starts at polar state ``x0`` (canonical units), its
    theta from the starting radius and its lengths in r0 = x0[0]."""
    r0 = x0[0]
    q0 = q_from_polar(ca.vertcat(r0, 0, x0[2], x0[3]), r0)
    return FirstOrderArc(q0, ac_tilde(ac, r0), R, T)


def arc_state(x0, arc, phi, q=None):
    """Canonical polar state at angle phi along ``arc`` started at ``x0`` (Eqs. 9-11), from
    the arc's first-order elements there or from ``q`` (e.g. :class:`SecondOrderArc`'s)."""
    r0 = x0[0]
    local = polar_from_q(arc.q(phi) if q is None else q, phi, r0)
    return ca.vertcat(local[0], x0[1] + phi, local[2], local[3])


def arc_end(x0, dtheta, ac, R, T, panels=4, nodes=8):
    """``(x1, dt, q3)`` after a fixed-attitude arc of ``dtheta`` rad (several revolutions
    are fine) from the polar state ``x0`` (canonical, ``ac`` times any throttle): the state,
    the time (TU, by ``panels`` Gauss-Legendre panels of ``nodes`` points) and q3 at the
    end, which must stay positive for the first-order arc to hold (for T >= 0 its smallest
    value on the arc).
    """
    arc = arc_frame(x0, ac, R, T)
    dt = 0
    for p in range(panels):
        dt += arc.time(dtheta * p / panels, dtheta * (p + 1) / panels, nodes)
    return arc_state(x0, arc, dtheta), x0[0] ** 1.5 * dt, arc.q(dtheta)[2]
