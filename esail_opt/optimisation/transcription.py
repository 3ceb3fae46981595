"""The transcription: a :class:`Problem` turned into a multiple-shooting NLP.

Decision variables, each scaled to order one, in this order: ``alpha[N]``, each segment's
constant pitch, rad; ``length[N]``, its arc angle, rad (or its duration, TU, for a method in
time); ``X[5 x N]``, the state [r, theta, v_r, v_theta, t] at its end; where free, the
departure anomaly ``nu0``, the throttles ``kappa[N]`` (a segment flies at kappa a_c), the
departure ``epoch``, ``ac_scale`` and ``vinf_angle``.  In 3-D ``X[9 x N]`` adds the orbital
plane's unit quaternion (theta inside it), and the clock angles ``delta[N]`` come last.

A segment is the method's Function (``segment_methods``), by default ``sub_arcs`` rectified
closed-form arcs (Eq. 12 for q, one Picard sweep; Eqs. 9-11 for the state), ``map``-ped so
that the MX NLP holds one copy of its graph.  Constraints: continuity X_{k+1} = F(X_k),
q3 >= margin at every sub-arc's end, equal lengths if asked, positive durations, the fixed
time of flight, the target at the last node (a 3-D body target's in cylindrical coordinates,
``goals._BodyTarget.cylindrical_constraints``) and the arrival window; r >= r_min bounds the nodes.
"""

import dataclasses
import math
import os
from dataclasses import dataclass

import casadi as ca
import numpy as np

from esail_opt.bodies import dates, lookup
from esail_opt.optimisation.nodes import node_cartesian_function
from esail_opt.optimisation.seed import Guess, initial_guess
from esail_opt.optimisation.segment_methods import ClosedForm


#: This process's share of the cores for the segments (:func:`share_cores`); None until
#: a run's pool worker is given one.
_SHARE = None


def share_cores(threads):
    """In a run's pool worker (once, from its initialiser): evaluate the segments of every
    NLP built in this process on ``threads`` threads, the worker's share of the cores."""
    global _SHARE
    _SHARE = int(threads)


def segment_threads():
    """Threads that evaluate the segments and their derivatives (independent given their
    nodes; the same optimum in the same iterations): a pool worker's :func:`share_cores`,
    else the machine's cores, at most 4."""
    if _SHARE is not None:
        return _SHARE
    return max(1, min(4, os.cpu_count() or 1))


@dataclass
class Transcription:
    """The NLP and the maps from its flat variable vector back to the schedule."""

    nlp: dict
    nlp_g: ca.Function  # (w, defects) -> g, to re-check the constraints at a returned point
    x0: np.ndarray  # scaled initial guess
    lbx: np.ndarray
    ubx: np.ndarray
    lbg: np.ndarray
    ubg: np.ndarray
    # (w, p) -> the schedule's parts, by name (:func:`_unpack_function`)
    unpack: ca.Function
    guess: Guess
    names: dict
    objective_unit: tuple = (1.0, "")  # (factor, unit) that shows the objective to a user
    # The NLP's parameters after the defects: the departure epoch (TU since J2000) and
    # the fixed time of flight (TU; 0 without one).  A scan changes them, not the NLP.
    epoch: float = 0.0
    tof: float = 0.0
    # Then the bodies' corrections (:func:`body_corrections`), zero unless held to the ephemeris.
    corrections: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(8))
    # What :meth:`start_of` needs: the scales, and whether the lengths are durations.
    scales: object = None
    in_time: bool = False

    @property
    def segments(self):
        return self.guess.alpha.size

    @property
    def rows(self):
        """Rows of a node: 5, or 9 in three dimensions (the plane's quaternion)."""
        return self.guess.nodes.shape[0]

    def parameters(self, defects=None):
        """The NLP's parameter vector: the segment defects of the defect correction (rows x N;
        default none), then the epoch, the time of flight and the bodies' corrections."""
        d = (np.zeros(self.rows * self.segments) if defects is None
             else np.ravel(defects, order="F"))
        return np.r_[d, self.epoch, self.tof, self.corrections]

    def at(self, problem):
        """This NLP with the parameters of ``problem``, a variant of the problem it was
        built for that differs only in its departure date or fixed time of flight."""
        tof = problem.fixed_tof()
        return dataclasses.replace(self, epoch=problem.epoch(),
                                   tof=0.0 if tof is None else tof)

    def start_of(self, problem, guess):
        """``guess`` (of this NLP's size and class) as a point of this NLP, scaled and
        clipped to its bounds: another model's optimum started on this NLP."""
        _, blocks = _variables(problem, guess, self.scales, self.in_time)
        return np.clip(blocks.stacked()[3], self.lbx, self.ubx)

    def constraints(self, w, defects=None):
        """The constraint values g at the flat point ``w`` (numpy), with the segment
        defects of the defect correction (rows x N; default none)."""
        return np.array(self.nlp_g(w, self.parameters(defects))).ravel()


def body_corrections(problem, result):
    """:attr:`Transcription.corrections` at ``result``'s dates: the departure body's
    ephemeris less its track at departure, then the target body's at arrival (polar,
    4 + 4, ``bodies.lookup.track_correction``; Cartesian in three dimensions, 6 + 6); zeros
    off the calendar and for a target that is not a real body."""
    if problem.three_d():
        body = getattr(problem.target, "body", None)
        arrival = result.epoch + float(np.sum(result.durations))
        return np.r_[lookup.track3_correction(problem.departure.body, result.epoch),
                     np.zeros(6) if body is None else lookup.track3_correction(body, arrival)]
    out = np.zeros(8)
    if not problem.dated():
        return out
    out[:4] = lookup.track_correction(problem.departure.body, result.epoch)
    body = getattr(problem.target, "body", None)
    if body is not None:
        out[4:] = lookup.track_correction(body, result.epoch + float(np.sum(result.durations)))
    return out


class _Blocks:
    """Named blocks of a vector with their bounds, stacked in the order they are added:
    the NLP's variables (with their start values) or its constraints."""

    def __init__(self):
        self.exprs, self.lo, self.hi, self.start, self.sizes = [], [], [], [], {}

    def add(self, name, expr, lo, hi, start=None):
        """Append block ``name``; ``lo``, ``hi`` and ``start`` are scalars or arrays of
        its shape, flattened column-major as ``casadi.vec`` flattens the block."""
        if expr.numel() == 0:
            return

        def flat(v):
            v = np.asarray(v, float)
            if v.size == expr.numel():
                return v.ravel(order="F")
            return np.broadcast_to(v, expr.shape).ravel(order="F")
        self.exprs.append(ca.vec(expr))
        self.lo.append(flat(lo))
        self.hi.append(flat(hi))
        self.start.append(flat(0.0 if start is None else start))
        self.sizes[name] = expr.numel()

    def stacked(self):
        """(expression, lower bounds, upper bounds, start values), each flat."""
        cat = lambda parts: np.concatenate(parts) if parts else np.zeros(0)
        return (ca.vertcat(*self.exprs), cat(self.lo), cat(self.hi), cat(self.start))


@dataclass
class _Scales:
    """Order-one scales of the variables: the guess's segment length for lengths, its whole
    angle for theta and its time of flight for t (radii and speeds are of order one).  Theta
    is first shifted by whole turns: a body's track counts its longitude from the ephemeris's
    first date, hundreds of radians back, which would bury the transfer's own angles in the
    last digits of Ipopt's tolerances."""

    length: float
    node: np.ndarray  # per row of a node [r, theta, v_r, v_theta, t]
    epoch: float  # the free departure epoch is this offset plus a variable in TU
    shift: np.ndarray  # per row of a node: whole turns of theta, 0 elsewhere

    @classmethod
    def of(cls, guess):
        turns = 2 * math.pi * round(float(guess.nodes[1, 0]) / (2 * math.pi))
        th = max(1.0, float(abs(guess.nodes[1, -1] - turns)))
        t = max(1.0, float(guess.nodes[4, -1]))
        # A 3-D node's quaternion rows are of order one already.
        extra = guess.nodes.shape[0] - 5
        return cls(float(np.mean(guess.lengths)), np.r_[1.0, th, 1.0, 1.0, t, np.ones(extra)],
                   float(guess.epoch), np.r_[0.0, turns, 0.0, 0.0, 0.0, np.zeros(extra)])

    def scaled(self, nodes):
        """Nodes (rows x N, numbers) in the NLP's scaled variables."""
        return (np.asarray(nodes, float) - self.shift[:, None]) / self.node[:, None]

    @property
    def time(self):
        return self.node[4]


def _pitch_bounds(problem):
    """Bounds of the pitch variables, rad."""
    if problem.sail.alpha_min_deg == -90 and problem.sail.alpha_max_deg == 90:
        # R and T depend on 2 alpha only, so -90 and +90 deg are one attitude and the full
        # box is a wall optima stop against; results report the pitch wrapped.
        return -np.inf, np.inf
    return problem.alpha_bounds()


def _node_bounds(problem, guess, scales, n):
    """Bounds of the rows x N scaled nodes.  r >= r_min is a bound; v_theta > 0 keeps the
    orbit prograde, as the closed form (q3 = 1/h) assumes; the revolution window, if
    any, boxes the last node's theta."""
    lo = np.tile([[max(problem.path.r_min_au, 1e-3)], [-np.inf], [-10.0], [1e-2], [0.0]], n)
    hi = np.tile([[100.0], [np.inf], [10.0], [20.0], [np.inf]], n)
    if problem.three_d():
        # Quaternion components: continuity keeps the norm; the box keeps trial points near it.
        lo, hi = np.vstack([lo, np.full((4, n), -1.5)]), np.vstack([hi, np.full((4, n), 1.5)])
    if guess.theta_window is not None:
        lo[1, -1], hi[1, -1] = guess.theta_window
    return scales.scaled(lo), scales.scaled(hi)


def _variables(problem, guess, scales, in_time):
    """The decision variables (the module's list), their bounds and start: MX, so that the
    mapped segment Function is one copy of the arc's graph (inlined SX arcs make the
    derivatives far dearer).  Every variable couples only neighbouring segments (the node
    carries the elapsed time; equal lengths are chained equalities, not one shared variable),
    so the constraint Jacobian is banded and cheap to colour."""
    n = guess.alpha.size
    free_nu = bool(getattr(problem.departure, "free_anomaly", False))
    kappa_bounds = problem.throttle_bounds()
    free_date = problem.free_date()
    free_ac = problem.objective.free_acceleration
    free_angle = problem.dated() and problem.departure.free_direction
    three_d = problem.three_d()
    v = {"alpha": ca.MX.sym("alpha", n), "length": ca.MX.sym("length", n),
         "nodes": ca.MX.sym("nodes", 9 if three_d else 5, n),
         "nu0": ca.MX.sym("nu0", 1 if free_nu else 0),
         "kappa": ca.MX.sym("kappa", 0 if kappa_bounds is None else n),
         "epoch": ca.MX.sym("epoch", 1 if free_date else 0),
         "ac_scale": ca.MX.sym("ac_scale", 1 if free_ac else 0),
         "vinf_angle": ca.MX.sym("vinf_angle", 1 if free_angle else 0),
         "delta": ca.MX.sym("delta", n if three_d else 0)}
    blocks = _Blocks()
    blocks.add("alpha", v["alpha"], *_pitch_bounds(problem), guess.alpha)
    max_angle = 2 * math.pi * problem.max_revolutions
    len_hi = (np.inf if in_time else
              (max_angle / n if problem.segments.equal else max_angle) / scales.length)
    blocks.add("length", v["length"], 1e-4 / scales.length, len_hi, guess.lengths / scales.length)
    blocks.add("nodes", v["nodes"], *_node_bounds(problem, guess, scales, n),
               scales.scaled(guess.nodes))
    blocks.add("nu0", v["nu0"], -4 * math.pi, 4 * math.pi, guess.nu0)
    k_lo, k_hi = (1.0, 1.0) if kappa_bounds is None else kappa_bounds
    blocks.add("kappa", v["kappa"], k_lo, k_hi, 1.0 if guess.throttle is None else guess.throttle)
    if free_date:
        # In TU from the guess's epoch: order one, where the epoch is hundreds of TU.
        lo, hi = (dates.tu_from_jd(jd) - scales.epoch for jd in problem.departure.window_jd)
        blocks.add("epoch", v["epoch"], lo, hi, guess.epoch - scales.epoch)
    # a_c stays inside the sail's own range, (0, 100] mm/s^2.
    blocks.add("ac_scale", v["ac_scale"], 1e-4, 100.0 / problem.sail.ac_mm_s2, guess.ac_scale)
    blocks.add("vinf_angle", v["vinf_angle"], -2 * math.pi, 2 * math.pi, guess.vinf_angle)
    # The clock comes after everything planar, so a planar NLP's layout is unchanged.
    blocks.add("delta", v["delta"], *problem.clock_bounds(),
               0.0 if guess.delta is None else guess.delta)
    return v, blocks


def _flight(problem, segment, v, p, scales, in_time, threads):
    """The segments flown from their start nodes (on at most ``threads`` threads):
    ends (with the defect parameter), q3, the angles and durations of the segments,
    and the final state and time."""
    n = v["alpha"].numel()
    nodes = v["nodes"] * ca.DM(scales.node) + ca.DM(scales.shift)
    dep = problem.departure
    epoch = scales.epoch + v["epoch"][0] if v["epoch"].numel() else p["epoch"]
    three_d = problem.three_d()
    if problem.dated():
        angle = v["vinf_angle"][0] if v["vinf_angle"].numel() else dep.seed_angle()
        x_start = (dep.nlp_plane_state(epoch, angle, p["corrections"][:6]) if three_d
                   else dep.nlp_state(epoch, angle) + p["corrections"][:4])
    else:
        x_start = dep.state(v["nu0"][0]) if v["nu0"].numel() else ca.DM(problem.x0())
    starts = ca.horzcat(ca.vertcat(x_start[:4], 0, x_start[4:]), nodes[:, :-1])
    ac_scale = v["ac_scale"][0] if v["ac_scale"].numel() else 1
    ac = problem.sail.ac * ac_scale * (v["kappa"].T if v["kappa"].numel() else 1)
    length = v["length"] * scales.length
    threads = min(threads, n)
    mapped = segment.map(n, "thread", threads) if threads > 1 else segment.map(n)
    controls = [v["alpha"].T] + ([v["delta"].T] if three_d else [])
    ends, q3 = mapped(starts, ac, *controls, length.T)
    # The defect correction (optimisation.error_control): a parameter, so one solver serves all.
    defects = ca.MX.sym("defects", nodes.shape[0], n)
    swept = (nodes[1, :] - starts[1, :]).T
    elapsed = (nodes[4, :] - starts[4, :]).T
    out = {"nodes": nodes, "x_start": x_start, "ends": ends + defects, "q3": ca.vec(q3),
           "defects": defects, "lengths": swept if in_time else length,
           "durations": length if in_time else elapsed,
           "xf": nodes[:4, -1], "tf": nodes[4, -1], "epoch": epoch, "ac_scale": ac_scale}
    if three_d:
        out["yf"] = node_cartesian_function()(nodes[:, -1])
    return out


def _constraints(problem, guess, v, p, flight, scales, in_time):
    """Continuity, validity, the segments' shape, the time of flight and the target."""
    n = v["alpha"].numel()
    g = _Blocks()
    g.add("continuity", (flight["ends"] - flight["nodes"]) / ca.DM(scales.node), 0, 0)
    g.add("q3", flight["q3"], problem.path.q3_margin, np.inf)
    if problem.segments.equal and n > 1:
        # In time the variables are durations: equal segments still mean equal angles.
        lengths = flight["lengths"] if in_time else v["length"]
        g.add("equal_lengths", lengths[1:] - lengths[:-1], 0, 0)
    # Durations positive: a segment running backwards in time is never physical.
    g.add("durations", flight["durations"] / scales.time, 0, np.inf)
    if problem.fixed_tof() is not None:
        g.add("tof", (flight["tf"] - p["tof"]) / scales.time, 0, 0)
    if hasattr(problem.target, "cylindrical_constraints") and "yf" in flight:
        # The longitude row holds the turn count k as the planar theta row does: the same classes.
        yf = flight["yf"] - (p["corrections"][6:] if problem.target.tracks_body else 0)
        target = problem.target.cylindrical_constraints(yf, flight["xf"][1], flight["tf"],
                                                        guess.revolutions_k, flight["epoch"])
        g.add("target", ca.vertcat(*target), 0, 0)
    elif problem.target is not None:
        # A body's correction moves its track onto the ephemeris.
        real = getattr(problem.target, "body", None) is not None
        xf = flight["xf"] - (p["corrections"][4:] if real else 0)
        target = problem.target.constraints(xf, flight["tf"], guess.revolutions_k,
                                            flight["epoch"])
        g.add("target", ca.vertcat(*target), 0, 0)
    window = getattr(problem.target, "arrival_jd", None)
    if window is not None:
        lo, hi = (dates.tu_from_jd(jd) - scales.epoch for jd in window)
        g.add("arrival", (flight["epoch"] - scales.epoch + flight["tf"]) / scales.time,
              lo / scales.time, hi / scales.time)
    return g


def transcribe(problem, method=None, guess=None, threads=None):
    """The :class:`Transcription` of ``problem``.  ``method`` (``segment_methods``, default
    :class:`ClosedForm`) flies the segments; its ``length_in`` says whether the lengths are
    arc angles (rad) or durations (TU).  In time, equal segments still mean equal angles,
    ``unpack``'s lengths are still the angles swept, and an empty q3 output adds no q3 rows.
    ``guess`` (default :func:`initial_guess`) sets N and the revolution class (turns,
    final-angle window), its ``lengths`` in the method's measure.  ``threads`` bounds the
    segments' threads (one for a ``serial`` method; default :func:`segment_threads`)."""
    method = ClosedForm() if method is None else method
    in_time = method.length_in == "time"
    segment = _checked_segment(problem, method.function(problem))
    guess = initial_guess(problem) if guess is None else guess
    scales = _Scales.of(guess)
    v, variables = _variables(problem, guess, scales, in_time)
    n_corr = 12 if problem.three_d() else 8
    params = {"epoch": ca.MX.sym("epoch"), "tof": ca.MX.sym("tof"),
              "corrections": ca.MX.sym("corrections", n_corr)}
    threads = 1 if method.serial else segment_threads() if threads is None else threads
    flight = _flight(problem, segment, v, params, scales, in_time, threads)
    g = _constraints(problem, guess, v, params, flight, scales, in_time)
    w, lbx, ubx, w0 = variables.stacked()
    g_expr, lbg, ubg, _ = g.stacked()
    p = ca.vertcat(ca.vec(flight["defects"]), params["epoch"], params["tof"],
                   params["corrections"])
    if problem.objective.free_acceleration:
        f = problem.sail.ac * flight["ac_scale"]
    else:
        f = problem.objective.cost(flight["xf"], flight["tf"])
    tof = problem.fixed_tof()
    return Transcription({"x": w, "p": p, "f": f, "g": g_expr},
                         ca.Function("g", [w, p], [g_expr], ["w", "p"], ["g"]),
                         np.clip(w0, lbx, ubx), lbx, ubx, lbg, ubg,
                         _unpack_function(problem, guess, v, flight, w, p), guess, g.sizes,
                         problem.objective.shown_as(), problem.epoch(),
                         0.0 if tof is None else tof, np.zeros(n_corr), scales, in_time)


def _checked_segment(problem, segment):
    """``segment``; ValueError if its inputs are not those of the problem's segments
    (planar or 3-D)."""
    if segment.n_in() != (5 if problem.three_d() else 4):
        raise ValueError(f"segment {segment.name()!r} has {segment.n_in()} inputs; a "
                         f"{'3-D' if problem.three_d() else 'planar'} problem's segment takes "
                         f"{5 if problem.three_d() else 4} (planar=True flies the planar ones)")
    return segment


def _unpack_function(problem, guess, v, flight, w, p):
    """The Function ``(w, p) ->`` the solution's parts (``Transcription.unpack``):
    a part the NLP does not vary (no free nu0, throttle, launch angle) is the guess's
    or the problem's constant."""
    nu0 = v["nu0"][0] if v["nu0"].numel() else ca.MX(guess.nu0)
    throttle = v["kappa"] if v["kappa"].numel() else ca.MX.ones(guess.alpha.size, 1)
    angle = (v["vinf_angle"][0] if v["vinf_angle"].numel()
             else ca.MX(problem.departure.seed_angle() if problem.dated() else 0.0))
    # Without a free epoch the parameter is an input of unpack too, so that it reports it.
    return ca.Function("unpack", [w, p], [v["alpha"], flight["lengths"], flight["nodes"],
                                          flight["durations"], flight["x_start"],
                                          flight["q3"], nu0, throttle, flight["epoch"],
                                          flight["ac_scale"], angle, v["delta"]],
                       ["w", "p"], ["alpha", "lengths", "nodes", "durations", "x_start", "q3",
                                    "nu0", "throttle", "epoch", "ac_scale", "vinf_angle",
                                    "delta"])
