"""How an NLP's segments are flown: the segment methods, as objects.

A multiple-shooting NLP (``optimisation.transcription``) flies each segment from its
start node with one segment Function, mapped over the segments.  Which Function is a
choice of method, and each method here knows how to build its own for a problem:

* :class:`ClosedForm`: the paper's rectified closed-form arcs (the default of every
  NLP), planar or in a turning plane;
* :class:`RK4`: fixed-step RK4 on Eqs. 1-2 (or, in three dimensions, on the turning
  plane's equations in the angle, or on the Cartesian equations in time);
* :class:`CVODES`: adaptive CVODES integration of Eqs. 1-2, in the angle or in time.

A method also says what its segments' lengths measure (``length_in``: the angle swept
or the duration) and whether its segments must be evaluated one after the other
(``serial``).  The benchmarks, the error control and the polish each pass a method;
the transcription builds the NLP the same way for all of them.
"""

import dataclasses
import functools
from dataclasses import dataclass
from typing import Optional

import casadi as ca

from esail_opt.errors import InputError
from esail_opt.physics import rotation
from esail_opt.physics.elements import cartesian_from_polar3d
from esail_opt.physics.thrust import EXACT
from esail_opt.propagation import compiled
from esail_opt.propagation.arcs import ArcModel
from esail_opt.propagation.rectified import flies_native, piece_function, rectified_function
from esail_opt.propagation.rectified3d import arc_function3d
from esail_opt.propagation.rk4 import rk4_segment, rk4_segment_turning, rk4_step3d
from esail_opt.propagation.simulate import CHECK_TOLERANCE, segment_integrator


@dataclass(frozen=True)
class ClosedForm:
    """The rectified closed-form segment (:func:`closed_form_segment`, or
    :func:`closed_form_segment3d` for a problem that flies in three dimensions), on
    ``model``'s arcs; default the problem's own (:func:`arc_model`)."""

    model: Optional[ArcModel] = None

    length_in = "theta"
    serial = False

    def function(self, problem):
        model = arc_model(problem) if self.model is None else self.model
        build = closed_form_segment3d if problem.three_d() else closed_form_segment
        return build(coefficients=problem.sail.coefficients, model=model)


@dataclass(frozen=True)
class RK4:
    """``steps`` fixed RK4 steps a segment, in the angle swept or, ``in_time``, in time:
    on Eqs. 1-2 (``rk4.rk4_segment``); in three dimensions on the turning plane's
    equations in the angle (``rk4.rk4_segment_turning``), or on the Cartesian equations
    in time (:func:`rk4_time_segment3d`, the 3-D polish's)."""

    steps: int
    in_time: bool = False
    #: In time in three dimensions (the 3-D polish's), compiled where compiling is on
    #: (``propagation.compiled``); False keeps the expanded SX segment, for a few
    #: evaluations that need no library.
    native: bool = True

    serial = False

    @property
    def length_in(self):
        return "time" if self.in_time else "theta"

    def function(self, problem):
        coefficients = problem.sail.coefficients
        if not problem.three_d():
            return rk4_segment(self.steps, coefficients, self.length_in)
        if self.in_time:
            return rk4_time_segment3d(self.steps, coefficients,
                                      self.native and compiled.enabled())
        return rk4_segment_turning(self.steps, coefficients)


@dataclass(frozen=True)
class CVODES:
    """CVODES on Eqs. 1-2, in the angle swept (:func:`cvodes_segment`, the benchmarks')
    or, ``in_time``, in time (:func:`cvodes_time_segment`, the planar polish's exact
    arcs).  Planar problems only.  ``margins``: the constant q3 rows of a segment in the
    angle, default the problem's sub-arcs (the closed form's constraint count)."""

    in_time: bool = False
    margins: Optional[int] = None

    # On two threads the Hessian of a CVODES theta segment differed from call to call
    # by up to 1e-11 (8 segments, 6 calls at one point; identical serially), enough for
    # one seed to fail and then succeed: determinism is worth more than the second core.
    serial = True

    @property
    def length_in(self):
        return "time" if self.in_time else "theta"

    def function(self, problem):
        if problem.three_d():
            raise ValueError("CVODES segments fly Eqs. 1-2 only; a 3-D problem takes "
                             "ClosedForm or RK4 (planar=True flies the planar ones)")
        if self.in_time:
            return cvodes_time_segment(problem.sail.coefficients)
        margins = problem.segments.sub_arcs if self.margins is None else self.margins
        return cvodes_segment(margins, problem.sail.coefficients)


def arc_model(problem):
    """The arcs ``problem``'s NLP flies: :class:`ArcModel`'s default with the problem's
    sub-arcs and extrapolation, compiled unless compiling is off (``ESAIL_OPT_COMPILE=0``;
    ``propagation.compiled``).  The verification's closed-form curve flies the same."""
    seg = problem.segments
    return ArcModel(sub_arcs=seg.sub_arcs, extrapolate=seg.extrapolate,
                    native=compiled.enabled())


@functools.lru_cache(maxsize=None)
def closed_form_segment(*, coefficients=EXACT, model=ArcModel()):
    """One constant-pitch segment of ``model.sub_arcs`` rectified closed-form arcs.

    It is ``rectified.rectified_function`` of one segment on ``model``'s arcs (by
    default second order, ending on the exact angular momentum, ``arcs.QUAD_NODES``
    Gauss-Legendre points, not extrapolated: ``propagation.arcs.ArcModel`` says why);
    the NLP restarts every segment from its node.

    Parameters
    ----------
    coefficients : tuple
        (b1, b2) of Eqs. 3-4.
    model : ArcModel
        The arcs.  With ``model.native`` they are compiled (``propagation.compiled``):
        the same arithmetic, with the derivatives Ipopt asks for run as C, and the
        segment's own graph of arc calls and its derivatives compiled too (a library
        linked against the arcs').  Where nothing can be compiled the segment is the
        expanded SX one, as with ``native=False``; where only the segment's graph fails
        to compile, it is that MX graph over the compiled arcs.

    Returns
    -------
    casadi.Function
        ``(x0[5], ac, alpha, dtheta) -> (x1[5], q3[sub_arcs])``: x = [r, theta, v_r,
        v_theta, t] canonical, and q3 is each sub-arc's validity margin at its end (the
        smallest over its whole and half arcs).  SX and expanded, or an ``External``
        (or MX) over the compiled arcs.
    """
    native = flies_native(coefficients=coefficients, model=model)
    chain = rectified_function(1, coefficients=coefficients, model=model)
    sym = ca.MX if native else ca.SX
    if not native:
        chain = chain.expand()
    x0 = sym.sym("x0", 5)
    ac, alpha, dtheta = sym.sym("ac"), sym.sym("alpha"), sym.sym("dtheta")
    xs, q3 = chain(x0, ac, alpha, dtheta)
    # Inlined compiled arcs each recompute the pitch's thrust factors; shared once,
    # the derivatives of the graph are cheaper.
    segment = ca.Function("segment", [x0, ac, alpha, dtheta], [xs[:, -1], q3.T],
                          ["x0", "ac", "alpha", "dtheta"], ["x1", "q3"], {"cse": native})
    if native:
        # The chain rule between the arcs compiled as well, calling the arcs' library:
        # on CasADi's virtual machine it was a large part of every Hessian and
        # constraint Jacobian.  One library per sub-arc count and extrapolation setting.
        segment = compiled.compiled(segment, (piece_function(coefficients=coefficients,
                                                             model=model),))
    return segment


@functools.lru_cache(maxsize=None)
def closed_form_segment3d(*, coefficients=EXACT, model=ArcModel()):
    """One segment of constant pitch and clock in three dimensions, ``model.sub_arcs``
    rectified closed-form arcs: ``(x0[9], ac, alpha, delta, dtheta) -> (x1[9],
    q3[sub_arcs])``, x = [r, theta, v_r, v_theta, t, qw, qx, qy, qz] (the planar arc's
    state inside the plane of the unit quaternion, ``propagation.rectified3d``).

    The arc is ``rectified3d.arc_function3d`` of one sample, expanded to SX, flown from
    the identity quaternion: an arc's polar rows never depend on its plane, and its
    plane ends as the start's times the turn that the identity ends at
    (``plane_turn.turned_plane``).  So the arcs chain the polar state and the product
    of their turns, and the segment's start quaternion enters once, in one product at
    its end -- the same quaternion products, grouped the other way (equal to rounding).
    The expensive part, whose Hessian Ipopt asks for, then takes the planar arc's inputs
    and the clock (10 in all, not 14).  With ``model.native`` the arc is compiled with
    its derivatives and the segment's chain compiled over it
    (``propagation.compiled``), as :func:`closed_form_segment` does in the plane;
    otherwise, or where nothing compiles, the segment is the expanded SX chain.
    """
    if model.extrapolate:
        raise InputError("segments.extrapolate = True is not available in three "
                         "dimensions; use False")
    one = dataclasses.replace(model.one_arc(), native=False)
    full = arc_function3d(1, coefficients=coefficients, model=one).expand()
    polar = ca.SX.sym("x0", 5)
    ac, alpha, delta, dtheta = (ca.SX.sym(n) for n in ("ac", "alpha", "delta", "dtheta"))
    xs, q3 = full(ca.vertcat(polar, *rotation.IDENTITY), ac, alpha, delta, dtheta)
    arc = ca.Function("arc_turn3d", [polar, ac, alpha, delta, dtheta],
                      [xs[:5, -1], xs[5:, -1], q3], ["x0", "ac", "alpha", "delta", "dtheta"],
                      ["x1", "turn", "q3"], {"cse": True})
    fast = compiled.compiled(arc) if model.native else arc
    native = fast is not arc
    sym = ca.MX if native else ca.SX
    x0 = sym.sym("x0", 9)
    ac, alpha, delta, dtheta = (sym.sym(n) for n in ("ac", "alpha", "delta", "dtheta"))
    x, turn, margins = x0[:5], None, []
    for _ in range(model.sub_arcs):
        x, step, q3 = fast(x, ac, alpha, delta, dtheta / model.sub_arcs)
        turn = step if turn is None else rotation.multiply(turn, step)
        margins.append(q3)
    segment = ca.Function("segment3d", [x0, ac, alpha, delta, dtheta],
                          [ca.vertcat(x, rotation.multiply(x0[5:], turn)),
                           ca.vertcat(*margins)],
                          ["x0", "ac", "alpha", "delta", "dtheta"], ["x1", "q3"],
                          {"cse": True})
    return compiled.compiled(segment, (arc,)) if native else segment


def node_from_swept(y, theta, quat_start):
    """The 3-D node [r, theta, v_r, v_theta, qw, qx, qy, qz] (no time row) of the
    Cartesian state ``y`` whose Sun-sail line has swept to the angle ``theta``, in the
    gauge of the turning plane (THEORY.md §9.3) that starts at ``quat_start``.

    The plane's frame never spins about its normal, so its x axis is where theta = 0:
    x = cos(theta) r_hat - sin(theta) t_hat, y = sin(theta) r_hat + cos(theta) t_hat,
    z = h_hat.  The quaternion is ``quat_start`` times the turn from its frame to that
    one, read off the rotation matrix by its scalar-first branch, smooth while the
    plane turns by less than a half turn over the arc.  CasADi operations: numbers or
    symbols.
    """
    pos, vel = y[:3], y[3:6]
    r = ca.norm_2(pos)
    r_hat = pos / r
    h_vec = ca.vertcat(pos[1] * vel[2] - pos[2] * vel[1], pos[2] * vel[0] - pos[0] * vel[2],
                       pos[0] * vel[1] - pos[1] * vel[0])
    h = ca.norm_2(h_vec)
    h_hat = h_vec / h
    t_hat = ca.vertcat(h_hat[1] * r_hat[2] - h_hat[2] * r_hat[1],
                       h_hat[2] * r_hat[0] - h_hat[0] * r_hat[2],
                       h_hat[0] * r_hat[1] - h_hat[1] * r_hat[0])
    c, s = ca.cos(theta), ca.sin(theta)
    frame = ca.horzcat(c * r_hat - s * t_hat, s * r_hat + c * t_hat, h_hat)
    quat_start = quat_start / ca.norm_2(quat_start)
    m = ca.mtimes(rotation.matrix(quat_start).T, frame)
    w = 0.5 * ca.sqrt(1 + m[0, 0] + m[1, 1] + m[2, 2])
    turn = ca.vertcat(w, (m[2, 1] - m[1, 2]) / (4 * w), (m[0, 2] - m[2, 0]) / (4 * w),
                      (m[1, 0] - m[0, 1]) / (4 * w))
    return ca.vertcat(r, theta, ca.dot(pos, vel) / r, h / r,
                      rotation.multiply(quat_start, turn))


@functools.lru_cache(maxsize=None)
def rk4_time_segment3d(steps, coefficients=EXACT, native=False):
    """The 3-D polish's segment: ``steps`` RK4 steps in time on the Cartesian equations
    (``rk4.rk4_step3d`` with the angle swept), between 3-D nodes.

    ``(x0[9], ac, alpha, delta, duration) -> (x1[9], q3[0])``, x = [r, theta, v_r,
    v_theta, t, qw, qx, qy, qz]: the node is turned into its Cartesian state
    (``elements.cartesian_from_polar3d``), flown, and named again by
    :func:`node_from_swept` with theta advanced by the angle swept, so that its ends
    are in the same gauge as the closed form's (:func:`closed_form_segment3d`) and the
    NLP's continuity rows mean the same thing for both.  q3 is empty, as for every
    exact arc.

    With ``native`` the RK4 step is compiled with its derivatives and the segment's
    chain of steps compiled over it (``propagation.compiled``), as the closed form's
    arcs are: on the virtual machine the Hessian of the Lagrangian of these segments
    was most of the 3-D polish's time.  One step library serves every step count.
    Otherwise, or where nothing compiles, the segment is SX, expanded.
    """
    step = rk4_step3d(coefficients, "time", swept=True)
    fast = compiled.compiled(step) if native else step
    sym = ca.MX if fast is not step else ca.SX
    x0 = sym.sym("x0", 9)
    ac, alpha, delta, duration = (sym.sym(n) for n in ("ac", "alpha", "delta", "duration"))
    quat = x0[5:] / ca.norm_2(x0[5:])
    y = ca.vertcat(cartesian_from_polar3d(x0[:4], quat), x0[4], x0[1])
    for _ in range(int(steps)):
        y = fast(y, ac, alpha, delta, duration / int(steps))
    node = node_from_swept(y[:6], y[7], quat)
    segment = ca.Function("segment_rk4_time3d", [x0, ac, alpha, delta, duration],
                          [ca.vertcat(node[:4], y[6], node[4:]), sym(0, 1)],
                          ["x0", "ac", "alpha", "delta", "duration"], ["x1", "q3"],
                          {"cse": True})
    if sym is ca.SX:
        return segment.expand()
    return compiled.compiled(segment, (step,))


@functools.lru_cache(maxsize=None)
def cvodes_segment(sub_arcs, coefficients=EXACT):
    """The same segment as :func:`closed_form_segment` with CVODES arcs on Eqs. 1-2.

    ``(x0[5], ac, alpha, dtheta) -> (x1[5], q3[sub_arcs])``: one CVODES integration in
    theta over the segment at tolerances 1e-12 (``simulate.segment_integrator``); CasADi
    differentiates it through forward and adjoint sensitivities.  There is no first-order
    arc, so its q3 outputs are a constant 1, which keeps the NLP's constraint count and
    structure identical to the closed form's (for the benchmark).
    """
    seg = segment_integrator(1, "theta", coefficients)
    x0 = ca.MX.sym("x0", 5)
    ac, alpha, dtheta = ca.MX.sym("ac"), ca.MX.sym("alpha"), ca.MX.sym("dtheta")
    x1 = seg(x0, ac, alpha, dtheta)[:, -1]
    return ca.Function("segment_cvodes", [x0, ac, alpha, dtheta],
                       [x1, ca.MX.ones(sub_arcs, 1)],
                       ["x0", "ac", "alpha", "dtheta"], ["x1", "q3"])


@functools.lru_cache(maxsize=None)
def cvodes_time_segment(coefficients=EXACT):
    """One constant-pitch segment of Eqs. 1-2 integrated by CVODES in time: the exact arc.

    ``(x0[5], ac, alpha, duration) -> (x1[5], q3[0])``: one CVODES integration over the
    segment's duration (TU) at tolerances 1e-15 (``simulate.segment_integrator``), which
    CasADi differentiates through forward and adjoint sensitivities.  The state's t row
    advances by the duration itself.  An exact arc has no first-order validity margin, so
    q3 is empty and ``transcription.transcribe`` (in time) adds no q3 rows.  Time,
    not theta, is the independent variable: the verification flies the schedule in time,
    so the polished NLP and its check integrate the same equations the same way.
    """
    # As tight as the verifier's check: at 1e-12 the polished optimum itself was 2-10 m
    # off where an independent DOP853 flight ended, so it could not meet a 1 m bound.
    seg = segment_integrator(1, "time", coefficients, CHECK_TOLERANCE)
    x0 = ca.MX.sym("x0", 5)
    ac, alpha, duration = ca.MX.sym("ac"), ca.MX.sym("alpha"), ca.MX.sym("duration")
    x1 = seg(x0, ac, alpha, duration)[:, -1]
    return ca.Function("segment_exact", [x0, ac, alpha, duration], [x1, ca.MX(0, 1)],
                       ["x0", "ac", "alpha", "duration"], ["x1", "q3"])
