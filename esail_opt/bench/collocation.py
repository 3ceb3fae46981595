"""Independent reference optima: minimum-time circle-to-circle E-sail transfers by direct
collocation of the full equations of motion (Eqs. 1-2).

Run it as a module, naming the JSON file to write (the tests read
``tests/reference/collocation_min_time.json``)::

    python -m esail_opt.bench.collocation --out collocation_min_time.json             # all
    python -m esail_opt.bench.collocation --out collocation_min_time.json earth_mars  # a subset

A subset run keeps the other cases already in the file.  ``esail-opt-bench lowthrust``
times this module's path to one optimum (:mod:`.lowthrust`).

It shares nothing with the optimiser but the physical model (``physics.dynamics.rhs``, exact
b1 = 3/4, b2 = 1/4).  The pitch alpha(t) is continuous, so the optimum bounds from below (up
to discretisation error) the time of any piecewise-constant schedule flown on Eqs. 1-2.

Problem: canonical units (au, mu = 1, TU), x = [r, theta, v_r, v_theta], from the circular
x(0) = [1, 0, 0, 1] to r = R, v_r = 0, v_theta = sqrt(1/R) at t = tf, theta(tf) free or, for
a rendezvous case (``phase_deg`` and ``k`` in CASES), theta(tf) = phase + tf R^-3/2 + 2 pi k
(k fixes the class: no revolution windows).  The sail is always on at a_c; minimise tf.

Transcription: tau = t / tf in [0, 1], N equal intervals; in each the state is the cubic
through the start and the Radau IIA points c = (0.155, 0.645, 1) (order 5), so the states
share one grid of 3N + 1 points.  The pitch is a decision variable at each collocation point
(:data:`CONTROL_DESCRIPTION`).  Boundary conditions are variable bounds, so the only
equalities are the defects.  Ipopt with MUMPS.

Globalisation: minimum-time transfers have local optima differing in revolutions, so each
case starts from constant-pitch integrations, k-revolution spirals (:func:`starts`) and
revolution windows; the distinct optima are re-solved on the reporting mesh N and verified
(one that does not fly is rejected), and the best is re-solved on 2N, the reported solution.

Verification (:func:`verify`): the control re-integrated on Eqs. 1-2 by DOP853 at
rtol = atol = 1e-12, and Pontryagin's principle checked from Ipopt's multipliers
(:func:`minimum_principle_alignment`).
"""

import argparse
import datetime
import json
import math
import time
from pathlib import Path

import casadi as ca
import numpy as np
from scipy.integrate import solve_ivp

# Only what an Ipopt status means: the reference's numbers owe nothing to the package.
from esail_opt.optimisation.outcome import Outcome

from esail_opt.physics import constants as units
from esail_opt.physics.dynamics import rhs
from esail_opt.physics.thrust import radial_transverse

CASES = {
    "earth_mars": {"ac_mm_s2": 1.0, "rf_au": 1.524},
    "earth_venus": {"ac_mm_s2": 1.0, "rf_au": 0.723},
    "earth_mars_low": {"ac_mm_s2": 0.1, "rf_au": 1.524},
    "earth_venus_low": {"ac_mm_s2": 0.1, "rf_au": 0.723},
    # Rendezvous with Mars, 44 deg ahead at departure, meeting it after gaining k = 0
    # whole turns on it (problems/earth_mars_rendezvous.py's best class).
    "earth_mars_rendezvous": {"ac_mm_s2": 1.0, "rf_au": 1.524, "phase_deg": 44.0, "k": 0},
}
R0_AU = 1.0

# Intervals per shortest orbital period on the way (at min(r0, R)).  The search mesh is
# coarser: Radau IIA there still tells basins apart and ranks them.
INTERVALS_PER_REV_SEARCH = 20
INTERVALS_PER_REV_REPORT = 60
MIN_INTERVALS_SEARCH = 24
MIN_INTERVALS_REPORT = 200

MAX_CPU_SECONDS = 30.0  # per Ipopt solve of the multistart (default of Transcription)

DEGREE = 3
RADAU = np.array(ca.collocation_points(DEGREE, "radau"))  # (c1, c2, c3 = 1)
NODES = np.concatenate(([0.0], RADAU))  # the interval's four interpolation points


def _lagrange_basis(nodes):
    """Lagrange basis polynomials on ``nodes`` as numpy poly1d objects."""
    basis = []
    for m, xm in enumerate(nodes):
        p = np.poly1d([1.0])
        for i, xi in enumerate(nodes):
            if i != m:
                p = p * np.poly1d([1.0, -xi]) / (xm - xi)
        basis.append(p)
    return basis


BASIS = _lagrange_basis(NODES)
# Row m: power-basis coefficients (highest first) of l_m, for np.polyval of a combination.
BASIS_COEF = np.array([b.coeffs for b in BASIS])
# D[j, m] = l_m'(c_j): derivative at the j-th Radau point of the state polynomial.
DIFF = np.array([[BASIS[m].deriv()(c) for m in range(DEGREE + 1)] for c in RADAU])
# Quadratic through the first interval's three collocation values, evaluated at 0: the
# control at t = 0 is not a decision variable (no collocation equation uses it).
EXTRAP0 = np.array([b(0.0) for b in _lagrange_basis(RADAU)])


# Eqs. 1-4 from the package, one casadi Function for the NLP and the verification alike.
_x = ca.SX.sym("x", 4)
_alpha = ca.SX.sym("alpha")
_ac = ca.SX.sym("ac")
_R, _T = radial_transverse(_alpha)
F_RHS = ca.Function("eqs_1_2", [_x, _alpha, _ac], [rhs(_x, _ac, _R, _T)])


def f_numeric(x, alpha, ac):
    return np.asarray(F_RHS(x, alpha, ac)).ravel()


def target_state(rf):
    return np.array([rf, 0.0, 1.0 / math.sqrt(rf)])  # r, v_r, v_theta (theta free)


def tof_lower_bound(ac, rf):
    """tf >= |h_f - h_0| / (a_c / 4): Eq. 2 gives dh/dt = a_c T with |T| <= 1/4."""
    return abs(math.sqrt(rf) - 1.0) / (ac / 4.0)


def shortest_period(rf):
    return 2.0 * math.pi * min(R0_AU, rf) ** 1.5


def intervals_for(tf, rf, per_rev, minimum):
    return max(minimum, int(math.ceil(per_rev * tf / shortest_period(rf))))


# ------------------------------------------------------------------ the NLP
def _interval_defects(N, ac):
    """One interval's collocation defects as a Function ``(states 4 x 4, controls 1 x 3,
    tf) -> 4 x 3``, mapped over the intervals so that the NLP graph stays small."""
    blk = ca.SX.sym("blk", 4, DEGREE + 1)
    ublk = ca.SX.sym("ublk", 1, DEGREE)
    s = ca.SX.sym("s")  # tf, shared
    defects = []
    for j in range(DEGREE):
        # N (blk @ D[j]) - tf f is O(tf), not O(tf / N): Ipopt's absolute tolerance
        # means the same on every mesh.
        slope = ca.mtimes(blk, ca.DM(DIFF[j, :]))
        defects.append(N * slope - s * F_RHS(blk[:, j + 1], ublk[j], ac))
    return ca.Function("interval", [blk, ublk, s], [ca.horzcat(*defects)])


def _ipopt_options(print_level, max_cpu_seconds):
    """The collocation's Ipopt options, each solve capped at ``max_cpu_seconds``."""
    return {
        "print_time": False,
        "ipopt.print_level": print_level,
        "ipopt.sb": "yes",
        "ipopt.linear_solver": "mumps",
        "ipopt.tol": 1e-10,
        "ipopt.acceptable_tol": 1e-8,
        "ipopt.acceptable_iter": 10,
        "ipopt.max_iter": 3000,
        # Far-off starts and infeasible windows grind on; other starts cover them.
        "ipopt.max_cpu_time": max_cpu_seconds,
    }


def _box(N, rf):
    """The bounds (lbx, ubx) of the decision vector for N intervals to radius rf."""
    npts = DEGREE * N + 1
    # States: physically generous boxes that only keep Ipopt out of r <= 0.
    lbz = np.tile(np.array([[0.2], [-1e4], [-5.0], [0.05]]), (1, npts))
    ubz = np.tile(np.array([[20.0], [1e4], [5.0], [5.0]]), (1, npts))
    lbz[:, 0] = ubz[:, 0] = [R0_AU, 0.0, 0.0, 1.0]  # circular 1 au, theta0 = 0
    tgt = target_state(rf)
    lbz[[0, 2, 3], -1] = ubz[[0, 2, 3], -1] = tgt  # circular target, theta free
    # Not boxed to [-90, 90] deg: Eqs. 3-4 depend on 2 alpha only, so a thrust passing the
    # (R, T) circle's inner point (1/2, 0) is smooth unwrapped but jumps from +90 to -90 deg
    # in alpha_n, which the polynomial cannot follow.  The physical pitch is the value
    # wrapped into [-90, 90).
    span = 2.0 * math.pi
    return (np.concatenate([lbz.ravel(order="F"), np.full(DEGREE * N, -span), [1e-2]]),
            np.concatenate([ubz.ravel(order="F"), np.full(DEGREE * N, span), [500.0]]))


class Transcription:
    """Radau IIA (3-stage) collocation NLP for one case and one mesh size N.

    Decision vector: states Z (4 x (3N+1), column-major), controls A (3N), tf.
    Grid point 3k + j (j = 0..3) of interval k sits at tau = (k + NODES[j]) / N.
    ``max_cpu_seconds`` caps each Ipopt solve (a timing may lift it to measure a slow solve).
    """

    def __init__(self, N, ac, rf, print_level=0, rendezvous=None,
                 max_cpu_seconds=MAX_CPU_SECONDS):
        self.N, self.ac, self.rf = N, ac, rf
        self.rendezvous = rendezvous
        npts = DEGREE * N + 1
        self.npts = npts
        Z = ca.SX.sym("Z", 4, npts)
        A = ca.SX.sym("A", 1, DEGREE * N)
        tf = ca.SX.sym("tf")
        cols = [DEGREE * k + m for k in range(N) for m in range(DEGREE + 1)]
        g = _interval_defects(N, ac).map(N)(Z[:, cols], A, ca.repmat(tf, 1, N))
        self.ng = g.numel()
        w = ca.vertcat(ca.vec(Z), ca.vec(A), tf)
        self.nw = w.numel()
        g = ca.vec(g)
        if rendezvous is not None:
            # Meet the body on its circular orbit: theta(tf) = phi0 + n tf + 2 pi k.
            phi0, k = rendezvous
            g = ca.vertcat(g, Z[1, -1] - (phi0 + tf * rf ** -1.5 + 2 * math.pi * k))
        self.solver = ca.nlpsol("radau_min_time", "ipopt", {"x": w, "f": tf, "g": g},
                                _ipopt_options(print_level, max_cpu_seconds))
        self.lbx, self.ubx = _box(N, rf)

    def tau_grid(self):
        k = np.arange(self.N)[:, None]
        return np.concatenate([[0.0], ((k + RADAU[None, :]) / self.N).ravel()])

    def pack(self, tf, Z, A):
        return np.concatenate([np.asarray(Z).ravel(order="F"), np.asarray(A).ravel(), [tf]])

    def unpack(self, w):
        w = np.asarray(w).ravel()
        nz = 4 * self.npts
        Z = w[:nz].reshape((4, self.npts), order="F")
        A = w[nz:nz + DEGREE * self.N]
        return float(w[-1]), Z, A

    def solve(self, guess, theta_window=None):
        """``guess`` is a callable tau -> (state 4 x n, alpha n) plus ``guess.tf``.

        ``theta_window`` = (lo, hi) (rad) optionally boxes the final theta, forcing a
        revolution count.  Returns a dict: tf, Z, A, N, lam_v, status, ok, ...
        """
        tau = self.tau_grid()
        Z0, A0 = guess(tau)
        A0 = A0[1:]
        lbx, ubx = self.lbx.copy(), self.ubx.copy()
        if theta_window is not None:
            i_theta_f = 4 * (self.npts - 1) + 1
            lbx[i_theta_f], ubx[i_theta_f] = theta_window
        w0 = np.clip(self.pack(guess.tf, Z0, A0), lbx, ubx)
        t0 = time.perf_counter()
        sol = self.solver(x0=w0, lbx=lbx, ubx=ubx, lbg=0.0, ubg=0.0)
        stats = self.solver.stats()
        tf, Z, A = self.unpack(sol["x"])
        # Multipliers of the v_r and v_theta defects (g is 4 x 3N, column by column).
        lam = np.asarray(sol["lam_g"]).ravel()[:4 * DEGREE * self.N].reshape(
            (4, DEGREE * self.N), order="F")
        return {
            "tf": tf, "Z": Z, "A": A, "N": self.N, "lam_v": lam[2:4],
            "status": stats["return_status"],
            "ok": Outcome.of(stats["return_status"]).found,
            "iterations": stats["iter_count"],
            "seconds": time.perf_counter() - t0,
            "max_defect": float(np.max(np.abs(np.asarray(sol["g"])))),
        }


# ------------------------------------------------------------------ initial guesses
class Guess:
    """A trajectory guess on normalised time: call with tau -> (Z, alpha)."""

    def __init__(self, tf, fn, label):
        self.tf, self.fn, self.label = tf, fn, label

    def __call__(self, tau):
        return self.fn(np.asarray(tau))


def constant_pitch_guess(ac, rf, alpha_deg):
    """Fly Eqs. 1-2 at constant pitch from the start until r first reaches rf."""
    alpha = math.radians(alpha_deg)
    outward = rf > R0_AU

    def hit(t, x):
        return x[0] - rf
    hit.terminal = True
    hit.direction = 1.0 if outward else -1.0

    t_max = 4.0 * tof_lower_bound(ac, rf) + 20.0
    sol = solve_ivp(lambda t, x: f_numeric(x, alpha, ac), (0.0, t_max), [R0_AU, 0.0, 0.0, 1.0],
                    method="DOP853", rtol=1e-9, atol=1e-9, events=hit, dense_output=True)
    if sol.status != 1:  # never reached the target radius
        return None
    tf = float(sol.t_events[0][0])

    def fn(tau):
        return sol.sol(tau * tf), np.full(tau.size, alpha)
    return Guess(tf, fn, f"constant pitch {alpha_deg:+.0f} deg")


def spiral_guess(ac, rf, revolutions):
    """A k-revolution spiral: r linear in time, circular speed, theta from the local rate."""
    sign = 1.0 if rf > R0_AU else -1.0
    s = np.linspace(0.0, 1.0, 2001)
    r_s = R0_AU + (rf - R0_AU) * s
    mean_rate = np.trapezoid(r_s**-1.5, s)
    tf = 2.0 * math.pi * revolutions / mean_rate

    def fn(tau):
        r = R0_AU + (rf - R0_AU) * tau
        if abs(rf - R0_AU) > 0:
            theta = tf * (-2.0) * (r**-0.5 - R0_AU**-0.5) / (rf - R0_AU)
        else:
            theta = tf * tau
        vr = np.full(tau.size, (rf - R0_AU) / tf)
        Z = np.vstack([r, theta, vr, r**-0.5])
        return Z, np.full(tau.size, sign * math.radians(45.0))
    return Guess(tf, fn, f"spiral {revolutions:g} rev")


def solution_guess(sol, label="previous solution"):
    """Re-use a solution on another mesh: linear interpolation on normalised time."""
    tau_src = np.concatenate([[0.0], ((np.arange(sol["N"])[:, None] + RADAU[None, :])
                                       / sol["N"]).ravel()])
    # A 5-point running median removes a lone outlying pitch (a discrete KKT point that
    # does not fly), so the re-solve lands on the genuine optimum nearby.
    alpha_src = control_at_points(sol["A"])
    padded = np.pad(alpha_src, 2, mode="edge")
    alpha_src = np.median(np.lib.stride_tricks.sliding_window_view(padded, 5), axis=1)

    def fn(tau):
        Z = np.vstack([np.interp(tau, tau_src, sol["Z"][i]) for i in range(4)])
        return Z, np.interp(tau, tau_src, alpha_src)
    return Guess(sol["tf"], fn, label)


# ------------------------------------------------------------------ control and verification
def control_at_points(A):
    """Continuous representative of the control on all 3N + 1 grid points, radians: Ipopt
    may return alpha + pi at a point (Eqs. 3-4 depend on 2 alpha), so the values are unwrapped
    with period pi; the value at t = 0 is extrapolated (:data:`EXTRAP0`)."""
    A = np.unwrap(np.asarray(A).ravel(), period=math.pi)
    alpha = np.concatenate([[EXTRAP0 @ A[:DEGREE]], A])
    # Shift by a whole number of half turns so that the start is a physical pitch.
    return alpha - math.pi * np.floor((alpha[0] + math.pi / 2) / math.pi)


def minimum_principle_alignment(sol):
    """Cosine between the NLP costate of (v_r, v_theta) and the pitch's thrust direction,
    (min, max) over the collocation points.

    With casadi's Lagrangian tf + lam' g and defects N D x - tf f, lam is minus the costate,
    so Pontryagin's principle (minimise H over alpha) is: maximise lam_v . (R, T)(alpha).  As
    (R, T) - (3/4, 0) = (cos 2a, sin 2a) / 4, at an optimum the cosine is +1 at every point;
    a point clearly below violates the principle.
    """
    a = np.asarray(sol["A"]).ravel()
    lam = sol["lam_v"]
    cosine = (lam[0] * np.cos(2 * a) + lam[1] * np.sin(2 * a)) / np.hypot(lam[0], lam[1])
    return float(np.min(cosine)), float(np.max(cosine))


def verify(sol, ac, rf, rendezvous=None):
    """Re-integrate Eqs. 1-2 with the continuous piecewise-cubic control, interval by
    interval so that DOP853 never steps across its kinks; the misses in km and m/s."""
    N, tf = sol["N"], sol["tf"]
    alpha_pts = control_at_points(sol["A"])
    h = tf / N
    x = np.array([R0_AU, 0.0, 0.0, 1.0])
    nfev = 0
    for k in range(N):
        coeffs = alpha_pts[DEGREE * k:DEGREE * k + DEGREE + 1]
        poly = coeffs @ BASIS_COEF
        t0 = k * h
        out = solve_ivp(lambda t, y: f_numeric(y, np.polyval(poly, (t - t0) / h), ac),
                        (t0, t0 + h), x,
                        method="DOP853", rtol=1e-12, atol=1e-12)
        x = out.y[:, -1]
        nfev += out.nfev
    tgt = target_state(rf)
    colloc_end = sol["Z"][:, -1]
    km = units.length_to_km(1.0)
    m_s = units.speed_to_km_s(1.0) * 1e3
    dv = np.hypot(x[2] - tgt[1], x[3] - tgt[2])
    out = {
        "final_state_integrated": {"r_au": x[0], "theta_rad": x[1], "v_r": x[2], "v_theta": x[3]},
        "miss_r_km": abs(x[0] - tgt[0]) * km,
        "miss_v_r_m_s": abs(x[2] - tgt[1]) * m_s,
        "miss_v_theta_m_s": abs(x[3] - tgt[2]) * m_s,
        "miss_v_m_s": dv * m_s,
        # theta is free, but its drift measures the transcription's own accuracy
        "theta_vs_collocation_km": abs(x[1] - colloc_end[1]) * x[0] * km,
        "rtol": 1e-12, "atol": 1e-12, "integrator": "scipy solve_ivp DOP853",
        "rhs_evaluations": int(nfev),
        "minimum_principle_cosine_min_max": minimum_principle_alignment(sol),
    }
    if rendezvous is not None:
        phi0, k = rendezvous
        body = phi0 + tf * rf ** -1.5 + 2 * math.pi * k
        out["miss_body_km"] = abs(x[1] - body) * x[0] * km
    return out


# ------------------------------------------------------------------ driver
def revolutions(sol):
    return float(sol["Z"][1, -1] / (2.0 * math.pi))


def distinct_optima(solutions):
    """Cluster converged solutions: same tf (1e-6 rel.) and same revolutions (1e-3)."""
    found = []
    for s in sorted((s for s in solutions if s["ok"]), key=lambda s: s["tf"]):
        if not any(abs(s["tf"] - o["tf"]) < 1e-6 * o["tf"]
                   and abs(revolutions(s) - revolutions(o)) < 1e-3 for o in found):
            found.append(s)
    return found


def starts(ac, rf):
    sign = 1.0 if rf > R0_AU else -1.0
    guesses = []
    for mag in (20, 25, 30, 35, 40, 45, 50, 55):
        g = constant_pitch_guess(ac, rf, sign * mag)
        if g is not None:
            guesses.append(g)
    # Spirals around the revolution count of the lower bound, at the local circular rate.
    lb = tof_lower_bound(ac, rf)
    s = np.linspace(0.0, 1.0, 2001)
    k_lb = lb * np.trapezoid((R0_AU + (rf - R0_AU) * s) ** -1.5, s) / (2 * math.pi)
    offsets = (-1.0, -0.5, 0.0, 0.5, 1.0, 1.5, 2.0)
    ks = sorted({max(0.5, round(2 * (k_lb + d)) / 2) for d in offsets})
    guesses += [spiral_guess(ac, rf, k) for k in ks]
    return guesses


def log(msg):
    print(f"[{time.strftime('%H:%M:%S')}] {msg}", flush=True)


# A converged point whose control, re-integrated, misses by more is a spurious optimum of
# the discrete problem: reported, never chosen.  Genuine optima miss by metres to a few km.
FLY_MISS_KM = 100.0
FLY_MISS_M_S = 0.1


def flies(ver):
    return (ver["miss_r_km"] < FLY_MISS_KM and ver["miss_v_m_s"] < FLY_MISS_M_S
            and ver.get("miss_body_km", 0.0) < FLY_MISS_KM)


def miss_summary(ver):
    keys = ("miss_r_km", "miss_v_m_s", "theta_vs_collocation_km",
            "minimum_principle_cosine_min_max", "miss_body_km")
    return {k: ver[k] for k in keys if k in ver}


def _search(ac, rf, rv):
    """Step 1: every start on the search mesh (sized for the longest guess), then the
    revolution windows.  Returns (runs, windows): the free solves, each with its
    ``start`` label, and the record of each window solve."""
    guesses = starts(ac, rf)
    n_search = intervals_for(max(g.tf for g in guesses), rf,
                             INTERVALS_PER_REV_SEARCH, MIN_INTERVALS_SEARCH)
    search = Transcription(n_search, ac, rf, rendezvous=rv)
    runs = []

    def record(s, label):
        s["start"] = label
        runs.append(s)
        log(f"  start {label:34s} -> {s['status']:26s} tf {units.time_to_days(s['tf']):10.4f} d "
            f"rev {revolutions(s):7.4f} ({s['iterations']} it, {s['seconds']:.1f} s)")

    for g in guesses:
        record(search.solve(g), f"{g.label} (tf0 {units.time_to_days(g.tf):.0f} d)")
    # A rendezvous's turn count is fixed by its constraint: no windows to visit.
    windows = [] if rv is not None else _revolution_windows(search, runs, ac, rf, record)
    return runs, windows


def _revolution_windows(search, runs, ac, rf, record):
    """Force theta_f into [2 pi k, 2 pi (k + 1)] from the matching spiral, then release the
    box (the released solve goes to ``record``), for k from one below the fewest revolutions
    found to two above the most (far fewer are infeasible: the angular momentum gain needs
    time).  Returns the record of each boxed solve."""
    free_revs = [revolutions(s) for s in runs if s["ok"]] or [0.0, 1.0]
    k_lo = max(0, int(math.floor(min(free_revs))) - 1)
    k_hi = int(math.floor(max(free_revs))) + 2
    windows = []
    for k in range(k_lo, k_hi + 1):
        window = (2 * math.pi * k, 2 * math.pi * (k + 1))
        boxed = search.solve(spiral_guess(ac, rf, k + 0.5), theta_window=window)
        windows.append({
            "revolutions_window": [k, k + 1], "status": boxed["status"],
            "tof_days": units.time_to_days(boxed["tf"]) if boxed["ok"] else None,
            "revolutions": revolutions(boxed) if boxed["ok"] else None,
            "intervals": boxed["N"],
            "note": "best transfer with theta_f boxed in the window (search mesh, not "
                    "verified); a bound-active result is not a free local optimum"})
        if not boxed["ok"]:
            log(f"  window {k}-{k + 1} rev: {boxed['status']}")
            continue
        record(search.solve(solution_guess(boxed)), f"window {k}-{k + 1} rev, released")
    return windows


def _verified_optima(optima, ac, rf, rv):
    """Step 2: every distinct local optimum re-solved on the reporting mesh N (sized for
    it) and verified.  Returns (refined, rejected): those that fly, and those that do not."""
    refined, rejected = [], []
    for o in optima:
        n_rep = intervals_for(o["tf"], rf, INTERVALS_PER_REV_REPORT, MIN_INTERVALS_REPORT)
        s = Transcription(n_rep, ac, rf, rendezvous=rv).solve(solution_guess(o))
        s["start"] = o["start"]
        if not s["ok"]:
            log(f"  optimum from {o['start']}: N={n_rep} failed ({s['status']})")
            continue
        s["verification"] = verify(s, ac, rf, rv)
        (refined if flies(s["verification"]) else rejected).append(s)
        log(f"  optimum from {o['start']:34s} N={n_rep}: tf {units.time_to_days(s['tf']):.6f} d "
            f"rev {revolutions(s):.4f}, miss {s['verification']['miss_r_km']:.2e} km "
            f"{s['verification']['miss_v_m_s']:.2e} m/s, PMP cosine "
            f"{s['verification']['minimum_principle_cosine_min_max'][0]:+.6f}")
    return refined, rejected


CONTROL_DESCRIPTION = (
    "Pitch in degrees on the fine mesh's 3*intervals_fine + 1 grid points; point "
    "3k + j of interval k (j = 0..3) is at t = tof * (k + nodes[j]) / "
    "intervals_fine. Inside interval k alpha(t) is the cubic Lagrange polynomial "
    "through points 3k..3k+3 at the nodes; point 0 is extrapolated (quadratic "
    "through interval 0's collocation values). Values are the continuous "
    "representative (unwrapped with period 180 deg, since Eqs. 3-4 depend on "
    "2 alpha only); the physical pitch alpha_n is the value wrapped into "
    "[-90, 90) deg, which gives the same R and T.")
METHOD = (
    "Direct collocation of Eqs. 1-2 (esail_opt.physics.dynamics.rhs, exact b1=3/4, "
    "b2=1/4), 3-stage Legendre-Gauss-Radau (Radau IIA, order 5) on N equal intervals "
    "of normalised time with free tf, pitch a decision variable at every collocation "
    "point (continuous piecewise-cubic alpha(t)), sail always on, Ipopt+MUMPS tol "
    "1e-10; multistart from constant-pitch forward integrations, k-revolution "
    "spirals and revolution-window solves; distinct optima re-solved and verified "
    "at N, the best re-solved at 2N; verification by DOP853 rtol=atol=1e-12.")


def _optimum_entry(s):
    """One verified (or rejected) optimum as the JSON lists it."""
    return {"tof_days": units.time_to_days(s["tf"]), "revolutions": revolutions(s),
            "intervals": s["N"], "found_from": s["start"],
            "verification": miss_summary(s["verification"])}


def _fine_entry(spec, best, fine, lb):
    """The reported optimum's own fields: the fine (2N) solution, the refinement study
    against ``best`` (N), its control and its Ipopt record."""
    rf = spec["rf_au"]
    tof_c, tof_f = units.time_to_days(best["tf"]), units.time_to_days(fine["tf"])
    return {
        "ac_mm_s2": spec["ac_mm_s2"], "r0_au": R0_AU, "rf_au": rf,
        "tof_days": tof_f, "tof_days_coarse": tof_c, "tof_days_fine": tof_f,
        "relative_change": abs(tof_f - tof_c) / tof_f,
        "intervals": best["N"], "intervals_fine": fine["N"],
        "intervals_per_shortest_period": best["N"] * shortest_period(rf) / best["tf"],
        "revolutions": revolutions(fine),
        "theta_f_rad": float(fine["Z"][1, -1]),
        "tof_lower_bound_days": units.time_to_days(lb),
        "ipopt": {"status": fine["status"], "iterations": fine["iterations"],
                  "max_defect": fine["max_defect"], "tol": 1e-10},
        "control": {"description": CONTROL_DESCRIPTION, "nodes": NODES.tolist(),
                    "alpha_deg": np.degrees(control_at_points(fine["A"])).tolist()},
        "final_state_collocation": {"r_au": float(fine["Z"][0, -1]),
                                    "theta_rad": float(fine["Z"][1, -1]),
                                    "v_r": float(fine["Z"][2, -1]),
                                    "v_theta": float(fine["Z"][3, -1])},
        "method": METHOD,
    }


def run_case(name, spec):
    """Solve one case of :data:`CASES` (multistart, verified optima, refinement study)
    and return its JSON entry."""
    ac = units.accel_from_mm_s2(spec["ac_mm_s2"])
    rf = spec["rf_au"]
    rv = ((math.radians(spec["phase_deg"]), spec["k"]) if "phase_deg" in spec else None)
    lb = tof_lower_bound(ac, rf)
    t_case = time.perf_counter()
    log(f"{name}: a_c = {spec['ac_mm_s2']} mm/s^2, R = {rf} au, "
        f"lower bound {units.time_to_days(lb):.3f} d")

    runs, windows = _search(ac, rf, rv)
    optima = distinct_optima(runs)
    if not optima:
        raise RuntimeError(f"{name}: no start converged")
    refined, rejected = _verified_optima(optima, ac, rf, rv)
    refined = distinct_optima(refined)
    if not refined:
        raise RuntimeError(f"{name}: no optimum survived verification")
    best = refined[0]

    n = best["N"]
    fine = Transcription(2 * n, ac, rf, rendezvous=rv).solve(solution_guess(best))
    if not fine["ok"]:
        raise RuntimeError(f"{name}: fine mesh failed: {fine['status']}")
    result = _fine_entry(spec, best, fine, lb)
    log(f"  refinement: N={n} {result['tof_days_coarse']:.8f} d, 2N={2 * n} "
        f"{result['tof_days_fine']:.8f} d, rel change {result['relative_change']:.2e}")

    ver = verify(fine, ac, rf, rv)
    log(f"  verification (2N): miss r {ver['miss_r_km']:.3e} km, v {ver['miss_v_m_s']:.3e} m/s, "
        f"along-track vs collocation {ver['theta_vs_collocation_km']:.3e} km")
    result.update({
        "local_optima": [_optimum_entry(s) for s in refined],
        "rejected_discrete_optima": [_optimum_entry(s) for s in rejected],
        "revolution_window_solves": windows,
        "starts": [{"start": s["start"], "status": s["status"],
                    "tof_days": units.time_to_days(s["tf"]), "revolutions": revolutions(s),
                    "intervals": s["N"]} for s in runs],
        "verification": ver,
        "runtime_seconds": time.perf_counter() - t_case,
    })
    if rv is not None:
        result["rendezvous"] = {"phase_deg": spec["phase_deg"], "k": spec["k"]}
    return result


def main(argv=None):
    """Solve the cases named on the command line (all by default) into ``--out``."""
    parser = argparse.ArgumentParser(
        prog="python -m esail_opt.bench.collocation",
        description="Reference optima of minimum-time E-sail transfers by direct "
                    "collocation of Eqs. 1-2.")
    parser.add_argument("--out", required=True, type=Path,
                        help="JSON file to write (cases already in it and not named are kept)")
    parser.add_argument("cases", nargs="*", metavar="CASE",
                        help=f"cases to solve (default all: {', '.join(CASES)})")
    args = parser.parse_args(argv)
    unknown = [n for n in args.cases if n not in CASES]
    if unknown:
        parser.error(f"unknown case(s) {unknown}; choose from {list(CASES)}")
    names = args.cases or list(CASES)
    data = json.loads(args.out.read_text()) if args.out.exists() else {}
    t0 = time.perf_counter()
    for name in names:
        data[name] = run_case(name, CASES[name])
        command = " ".join(["python -m esail_opt.bench.collocation --out", str(args.out),
                            *args.cases])
        stamp = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
        data["how"] = (
            f"Written by `{command}` on {stamp}, {time.perf_counter() - t0:.0f} s of "
            "computing for the cases of that run"
            + ("" if not args.cases else "; cases not named in it were kept from earlier runs")
            + ". Continuous-pitch Radau collocation of Eqs. 1-2 with casadi + Ipopt; see the "
            "module's docstring.")
        data["units"] = ("tof in days (1 day = 86400 s), radii in au, canonical velocities in "
                         "sqrt(mu/au); TU_DAYS = %.10f" % units.TU_DAYS)
        # After every case: an interrupted run keeps what it finished.
        args.out.write_text(json.dumps(data, indent=1) + "\n")
    log(f"done in {time.perf_counter() - t0:.0f} s -> {args.out}")


if __name__ == "__main__":
    main()
