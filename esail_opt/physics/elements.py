"""Conversions between the polar state, Bombardelli's elements q and classical elements.

The polar state is ``x = [r, theta, v_r, v_theta]`` in canonical units (au, rad, au/TU,
au/TU, mu = 1).  The elements q of Eq. 5 are dimensionless (lengths in a reference radius
r0, speeds in sqrt(mu / r0)), theta from the polar state's fixed direction.
"""

import functools

import casadi as ca
import numpy as np

from esail_opt.physics import rotation


def q_from_polar(x, r0):
    """Elements q (Eq. 5) of a polar state, normalised by the radius r0: the inverse of
    Eqs. 9-11, smooth for every e < 1."""
    r, th, vr, vt = x[0], x[1], x[2], x[3]
    scale = ca.sqrt(r0)
    vr_n, vt_n = vr * scale, vt * scale
    q3 = r0 / (r * vt_n)
    q1 = ca.cos(th) * (vt_n - q3) + ca.sin(th) * vr_n
    q2 = ca.sin(th) * (vt_n - q3) - ca.cos(th) * vr_n
    return ca.vertcat(q1, q2, q3)


def s_of(q, theta):
    """s = q1 cos(theta) + q2 sin(theta) + q3 (Eqs. 9-11: r = r0 / (q3 s), v_theta is
    s in sqrt(mu / r0))."""
    return q[0] * ca.cos(theta) + q[1] * ca.sin(theta) + q[2]


def polar_from_q(q, theta, r0):
    """Polar state at angle theta from elements q normalised by r0 (Eqs. 9-11)."""
    q1, q2, q3 = q[0], q[1], q[2]
    s = s_of(q, theta)
    speed = 1 / ca.sqrt(r0)
    return ca.vertcat(
        r0 / (q3 * s),
        theta,
        speed * (q1 * ca.sin(theta) - q2 * ca.cos(theta)),
        speed * s,
    )


def eccentricity_vector(x):
    """Osculating eccentricity vector (e cos omega, e sin omega), mu = 1; smooth at e = 0,
    where the apse line is undefined."""
    r, th, vr, vt = x[0], x[1], x[2], x[3]
    h = r * vt
    ec_f, es_f = h * vt - 1, h * vr
    return ca.vertcat(
        ec_f * ca.cos(th) + es_f * ca.sin(th),
        ec_f * ca.sin(th) - es_f * ca.cos(th),
    )


def orbital_energy(x):
    """Specific orbital energy v^2/2 - 1/r of a polar state, mu = 1 (negative while bound)."""
    return 0.5 * (x[2] ** 2 + x[3] ** 2) - 1 / x[0]


def classical_from_polar(x):
    """Osculating (a, e, omega, h, nu) of a polar state, mu = 1.  omega and nu have no
    derivative at e = 0; use :func:`eccentricity_vector` where derivatives are needed."""
    a = -0.5 / orbital_energy(x)
    ev = eccentricity_vector(x)
    e = ca.sqrt(ev[0] ** 2 + ev[1] ** 2)
    omega = ca.atan2(ev[1], ev[0])
    return a, e, omega, x[0] * x[3], x[1] - omega


@functools.lru_cache(maxsize=None)
def _classical(count):
    x = ca.SX.sym("x", 4)
    return ca.Function("classical", [x], [ca.vertcat(*classical_from_polar(x)[:count])])


def classical_columns(xs, count=2):
    """The first ``count`` of :func:`classical_from_polar`'s elements (a, e, omega, h,
    nu) of every column of the polar states ``xs`` [4+ x M], as numbers [count x M]."""
    xs = np.asarray(xs, float)[:4]
    return np.array(_classical(count).map(xs.shape[1])(xs), float).reshape(count, -1)


def polar_from_classical(a, e, omega, nu):
    """Polar state on the orbit (a, e, omega) at true anomaly nu, theta = omega + nu."""
    p = a * (1 - e**2)
    w = 1 + e * ca.cos(nu)
    return ca.vertcat(p / w, omega + nu, e * ca.sin(nu) / ca.sqrt(p), w / ca.sqrt(p))


def parking_q0(e0, theta0):
    """Initial elements on the parking orbit with theta from its apse line (Eq. 8)."""
    return ca.vertcat(e0, 0, 1) / ca.sqrt(1 + e0 * ca.cos(theta0))


def ac_tilde(ac, r0):
    """Dimensionless characteristic acceleration a~_c of Eq. 7: ac r0, with ac canonical
    (mu/au^2), r_E = 1 au and r0 in au."""
    return ac * r0


def cartesian_from_polar3d(x, quat):
    """Cartesian state ``[x, y, z, vx, vy, vz]`` of the polar state ``x = [r, theta, v_r,
    v_theta]`` in the plane of unit quaternion ``quat``.

    ``quat`` takes the plane's frame (x along theta = 0, z along r x v) to the fixed frame
    (the ecliptic of J2000 for real bodies; THEORY.md §9.3).  The frame turns about r_hat
    only, so its turn adds nothing to the velocity.  The identity gives the planar model's
    state in the fixed x-y plane.
    """
    r, th, vr, vt = x[0], x[1], x[2], x[3]
    c, s = ca.cos(th), ca.sin(th)
    pos = rotation.rotate(quat, ca.vertcat(r * c, r * s, 0))
    vel = rotation.rotate(quat, ca.vertcat(vr * c - vt * s, vr * s + vt * c, 0))
    return ca.vertcat(pos, vel)


def polar3d_from_cartesian(y):
    """Polar state and plane quaternion ``(x[4], quat[4])`` of a Cartesian state.

    The quaternion is the smallest rotation that takes the fixed z axis to h_hat, theta
    measured from its image of the fixed x axis: at inclination 0 the identity and the
    longitude, as in the planar model.  Undefined for an exactly retrograde orbit
    (h_hat = -z).
    """
    pos, vel = y[:3], y[3:6]
    h_vec = ca.vertcat(pos[1] * vel[2] - pos[2] * vel[1], pos[2] * vel[0] - pos[0] * vel[2],
                       pos[0] * vel[1] - pos[1] * vel[0])
    h = ca.norm_2(h_vec)
    hx, hy, hz = h_vec[0] / h, h_vec[1] / h, h_vec[2] / h
    quat = ca.vertcat(1 + hz, -hy, hx, 0)
    quat = quat / ca.norm_2(quat)
    local = ca.mtimes(rotation.matrix(quat).T, pos)
    r = ca.norm_2(pos)
    vr = ca.dot(pos, vel) / r
    return ca.vertcat(r, ca.atan2(local[1], local[0]), vr, h / r), quat


def plane_normal(quat):
    """h_hat, the unit normal of the plane of ``quat``, in the fixed frame."""
    return rotation.rotate(quat, ca.vertcat(0, 0, 1))


def inclination_and_node(quat):
    """Inclination in [0, pi] and longitude of the ascending node of the plane of
    ``quat``, radians (the node is undefined, and its derivative too, at inclination 0)."""
    n = plane_normal(quat)
    return ca.atan2(ca.sqrt(n[0] ** 2 + n[1] ** 2), n[2]), ca.atan2(n[0], -n[1])
