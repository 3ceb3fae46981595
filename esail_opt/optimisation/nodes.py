"""The NLP's nodes: their rows, their Cartesian state, and the segments flown through them.

A node is the state at a segment's end: [r, theta, v_r, v_theta, t] in the plane, and in
three dimensions [r, theta, v_r, v_theta, t, qw, qx, qy, qz], theta inside the orbital
plane that the unit quaternion turns the ecliptic into (THEORY.md §9.3).
"""

import functools

import casadi as ca
import numpy as np

from esail_opt.optimisation.segment_methods import ClosedForm
from esail_opt.physics.elements import cartesian_from_polar3d


def start_node(x_start):
    """The first segment's start node, with time 0: [r, theta, v_r, v_theta, 0], or in
    three dimensions [r, theta, v_r, v_theta, 0, qw, qx, qy, qz] from the 8-row start."""
    x = np.asarray(x_start, float).ravel()
    return np.r_[x[:4], 0.0, x[4:]]


@functools.lru_cache(maxsize=None)
def node_cartesian_function():
    """``node[9] -> [x, y, z, vx, vy, vz]``, the quaternion normalised: SX, so that the
    NLP's final state costs its derivatives a small block, not an MX graph."""
    node = ca.SX.sym("node", 9)
    quat = node[5:9] / ca.norm_2(node[5:9])
    return ca.Function("node_cartesian", [node], [cartesian_from_polar3d(node[:4], quat)])


def node_cartesian(node):
    """:func:`node_cartesian_function` of a 3-D node, as numbers."""
    return np.array(node_cartesian_function()(np.asarray(node, float).ravel()), float).ravel()


def flown_segments(problem, alpha, lengths, x_start, throttle=None, delta=None):
    """The NLP's own chain of segments flown forward from ``x_start`` (no continuity
    defects): node states [5 x N+1] with time (9 rows in three dimensions, from an
    8-row ``x_start``), for checks and tests.  ``throttle`` is kappa per segment,
    default 1; ``delta`` the clock per segment in three dimensions, default 0."""
    n = len(alpha)
    kappa = np.ones(n) if throttle is None else np.asarray(throttle, float)
    x = start_node(x_start)
    controls = [np.asarray(alpha, float)[None, :]]
    if problem.three_d():
        controls.append((np.zeros(n) if delta is None else np.asarray(delta, float))[None, :])
    # One accumulated call, not one Python call per segment.
    ends = ClosedForm().function(problem).mapaccum(n)(
        x, problem.sail.ac * kappa[None, :], *controls,
        np.asarray(lengths, float)[None, :])[0]
    return np.column_stack([x, np.array(ends)])
