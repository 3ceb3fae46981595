"""How an NLP's segments are flown: the segment methods, as objects.

The multiple-shooting NLP (``optimisation.transcription``) flies each segment from its
start node with one segment Function, mapped over the segments.  A method builds that
Function for a problem (:class:`ClosedForm`, the default; :class:`RK4`; :class:`CVODES`)
and says what its lengths measure (``length_in``: the angle swept or the duration) and
whether its segments must be evaluated one after the other (``serial``).
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
    #: In time in three dimensions, compiled where compiling is on; False keeps the
    #: expanded SX segment, for a few evaluations that need no library.
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

    # On two threads a CVODES theta segment's Hessian varied between calls by up to 1e-11,
    # enough to flip a solve's outcome: determinism is worth more than the second core.
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
    """The arcs ``problem``'s NLP (and the verification's closed-form curve) flies: the
    problem's sub-arcs and extrapolation, compiled unless ``ESAIL_OPT_COMPILE=0``."""
    seg = problem.segments
    return ArcModel(sub_arcs=seg.sub_arcs, extrapolate=seg.extrapolate,
                    native=compiled.enabled())


@functools.lru_cache(maxsize=None)
def closed_form_segment(*, coefficients=EXACT, model=ArcModel()):
    """One constant-pitch segment of ``model.sub_arcs`` rectified closed-form arcs
    (``rectified.rectified_function`` of one segment; ``propagation.arcs.ArcModel`` says
    why its defaults): ``(x0[5], ac, alpha, dtheta) -> (x1[5], q3[sub_arcs])``, x = [r,
    theta, v_r, v_theta, t] canonical, q3 each sub-arc's validity margin at its end (the
    smallest over its whole and half arcs).  ``coefficients`` are (b1, b2) of Eqs. 3-4.

    With ``model.native`` the arcs and the graph over them are compiled
    (``propagation.compiled``); else, or where nothing compiles, it is expanded SX.
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
        # The chain rule between the arcs compiled too: on CasADi's virtual machine it was
        # a large part of every Hessian and Jacobian.
        segment = compiled.compiled(segment, (piece_function(coefficients=coefficients,
                                                             model=model),))
    return segment


@functools.lru_cache(maxsize=None)
def closed_form_segment3d(*, coefficients=EXACT, model=ArcModel()):
    """One segment of constant pitch and clock in three dimensions, ``model.sub_arcs``
    rectified closed-form arcs: ``(x0[9], ac, alpha, delta, dtheta) -> (x1[9],
    q3[sub_arcs])``, x = [r, theta, v_r, v_theta, t, qw, qx, qy, qz]
    (``propagation.rectified3d``); InputError for an extrapolated ``model``.

    Each arc is flown from the identity quaternion (its polar rows never depend on its
    plane, ``plane_turn.turned_plane``) and the start quaternion applied once at the end,
    so the expensive part takes 10 inputs, not 14.  Compiled as :func:`closed_form_segment`.
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

    The plane's frame never spins about its normal, so x = cos(theta) r_hat - sin(theta)
    t_hat, y = sin(theta) r_hat + cos(theta) t_hat, z = h_hat; the quaternion is
    ``quat_start`` times the turn to that frame (scalar-first branch: smooth while the
    plane turns by less than a half turn).  Numbers or CasADi symbols.
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
    (``rk4.rk4_step3d`` with the angle swept), ``(x0[9], ac, alpha, delta, duration) ->
    (x1[9], q3[0])``.

    The end is named by :func:`node_from_swept`, in the closed form's gauge, so that the
    continuity rows mean the same for both.  ``native`` compiles it (``propagation.compiled``):
    on the virtual machine its Hessian was most of the 3-D polish's time.
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
    """:func:`closed_form_segment`'s signature flown by one CVODES integration of Eqs. 1-2
    in theta (``simulate.segment_integrator``), differentiated through its sensitivities;
    q3 is a constant 1, so that the NLP's structure is the closed form's (for the
    benchmark).
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
    """One constant-pitch segment of Eqs. 1-2 integrated by CVODES in time, the exact arc:
    ``(x0[5], ac, alpha, duration) -> (x1[5], q3[0])``, duration in TU, differentiated
    through CVODES's sensitivities; q3 is empty, so no q3 rows.  In time, not theta, as the
    verification flies, so that both integrate the same equations the same way.
    """
    # As tight as the verifier's check: at 1e-12 the polished optimum was 2-10 m off an
    # independent flight, over the 1 m bound.
    seg = segment_integrator(1, "time", coefficients, CHECK_TOLERANCE)
    x0 = ca.MX.sym("x0", 5)
    ac, alpha, duration = ca.MX.sym("ac"), ca.MX.sym("alpha"), ca.MX.sym("duration")
    x1 = seg(x0, ac, alpha, duration)[:, -1]
    return ca.Function("segment_exact", [x0, ac, alpha, duration], [x1, ca.MX(0, 1)],
                       ["x0", "ac", "alpha", "duration"], ["x1", "q3"])
