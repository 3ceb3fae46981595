"""Unit quaternions as the orientation of an orbital plane, in CasADi operations.

A quaternion is a 4-vector ``[w, x, y, z]``, scalar first.  ``p`` rotates a vector v
(given in the rotated frame) into the fixed frame as p v p*: that is, the columns of
:func:`matrix` are the rotated frame's axes in the fixed frame.  Every function accepts
floats, ``DM``, ``SX`` and ``MX``.
"""

import math

import casadi as ca

IDENTITY = (1.0, 0.0, 0.0, 0.0)

#: Terms of the series of cos(|v|/2) and sin(|v|/2)/|v| in |v|^2 used below |v| = 1,
#: where the 9th term is below 1e-20.
_SERIES_TERMS = 9


def multiply(p, q):
    """The product p q: first rotate by q, then by p, in the fixed frame's view; in
    frames, p q takes q's coordinates to p's rotated frame, then to the fixed frame."""
    pw, px, py, pz = p[0], p[1], p[2], p[3]
    qw, qx, qy, qz = q[0], q[1], q[2], q[3]
    return ca.vertcat(
        pw * qw - px * qx - py * qy - pz * qz,
        pw * qx + px * qw + py * qz - pz * qy,
        pw * qy - px * qz + py * qw + pz * qx,
        pw * qz + px * qy - py * qx + pz * qw,
    )


def matrix(q):
    """The rotation matrix of unit quaternion q: columns are the rotated axes."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    return ca.vertcat(
        ca.horzcat(1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)),
        ca.horzcat(2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)),
        ca.horzcat(2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)),
    )


def rotate(q, v):
    """q v q*: vector v, given in q's rotated frame, in the fixed frame."""
    return ca.mtimes(matrix(q), ca.vertcat(v[0], v[1], v[2]))


def _half_angle(a):
    """cos(sqrt(a)/2) and sin(sqrt(a)/2)/sqrt(a), finite with every derivative at a = 0.

    Below a = 1 the even power series in a serve; above, the direct quotient divides by
    a copy of sqrt(a) that the series branch replaces by 1, so no branch meets 0/0."""
    small = a < 1
    c_series, s_series = 0.0, 0.0
    # Horner in a: cos(x/2) = sum (-a/4)^k / (2k)!, sin(x/2)/x = sum (-a/4)^k / (2 (2k+1)!).
    for k in range(_SERIES_TERMS - 1, -1, -1):
        c_series = c_series * a + (-0.25) ** k / math.factorial(2 * k)
        s_series = s_series * a + (-0.25) ** k / (2 * math.factorial(2 * k + 1))
    norm = ca.sqrt(ca.if_else(small, 1.0, a))
    return (ca.if_else(small, c_series, ca.cos(norm / 2)),
            ca.if_else(small, s_series, ca.sin(norm / 2) / norm))


def from_rotation_vector(v):
    """The unit quaternion exp(v/2) of a rotation by |v| about v / |v| (v = 0: identity),
    smooth in v everywhere."""
    c, s = _half_angle(v[0] ** 2 + v[1] ** 2 + v[2] ** 2)
    return ca.vertcat(c, s * v[0], s * v[1], s * v[2])
