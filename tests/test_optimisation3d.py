"""Optimisation in three dimensions: the 3-D segment, the problem's switches, the gauge of
the error control's nodes, and the Mars rendezvous flown again outside the package.

The references are computed here: the Cartesian equations and the E-sail's thrust
a = (a_c/2)(r_E/r)[r_hat + (r_hat . n) n] written out again, flown by scipy's DOP853,
and DE421 read through jplephem and rotated to the ecliptic here.
"""

import dataclasses
import math

import casadi as ca
import numpy as np
import pytest
from scipy.integrate import solve_ivp

import esail_opt as eo
from esail_opt.app import schema
from esail_opt.errors import InputError
from esail_opt.propagation.arcs import ArcModel
from esail_opt.optimisation import error_control, multistart, pipeline
from esail_opt.optimisation.error_control import node_near
from esail_opt.optimisation.segment_methods import (ClosedForm, closed_form_segment3d,
                                                    node_from_swept, rk4_time_segment3d)
from esail_opt.optimisation.nodes import flown_segments, node_cartesian
from esail_opt.optimisation.seed import initial_guess, lifted_guess
from test_rectified3d import fly_turning_dop853

# Constants written out again here, not taken from the package.
AU_KM = 149597870.7
GM_SUN = 1.32712440018e20  # m^3/s^2
TU_DAYS = math.sqrt((AU_KM * 1e3) ** 3 / GM_SUN) / 86400.0
EPS = 84381.448 * math.pi / 180 / 3600


def mars_problem(**more):
    fields = dict(name="em3d", departure=eo.BodyDeparture(body="earth", date="2031-01-01"),
                  sail=eo.Sail(ac_mm_s2=1.0), segments=eo.Segments(count=20, sub_arcs=2),
                  objective=eo.MinTime(), target=eo.BodyRendezvous(body="mars"),
                  planar=False)
    return eo.Problem(**{**fields, **more})


def esail_rhs(ac, alpha, delta):
    """The Cartesian equations with the E-sail's exact thrust, from the sail's normal n
    at pitch alpha from r_hat, turned by delta about r_hat (0: toward t_hat)."""
    def rhs(_, y):
        pos, vel = y[:3], y[3:]
        r = np.linalg.norm(pos)
        r_hat = pos / r
        h = np.cross(pos, vel)
        h_hat = h / np.linalg.norm(h)
        t_hat = np.cross(h_hat, r_hat)
        n = (math.cos(alpha) * r_hat
             + math.sin(alpha) * (math.cos(delta) * t_hat + math.sin(delta) * h_hat))
        thrust = 0.5 * ac / r * (r_hat + np.dot(r_hat, n) * n)
        return np.r_[vel, -pos / r**3 + thrust]
    return rhs


def de421_ecliptic(segment, jd):
    """Heliocentric ecliptic-J2000 state (au, au/TU) of a DE421 segment, read here."""
    import de421
    from jplephem import Ephemeris

    eph = Ephemeris(de421)
    pos = np.ravel(eph.position(segment, jd) - eph.position("sun", jd))
    vel = np.ravel(eph.position_and_velocity(segment, jd)[1]
                   - eph.position_and_velocity("sun", jd)[1])
    c, s = math.cos(EPS), math.sin(EPS)
    turn = np.array([[1, 0, 0], [0, c, s], [0, -s, c]])
    return np.r_[turn @ pos / AU_KM, turn @ vel * TU_DAYS / AU_KM]


def fly_schedule(problem, result, rtol=1e-12, atol=1e-13):
    """``result``'s schedule (pitch, clock, throttle and duration per segment) flown here
    by DOP853 on the Cartesian equations from DE421's Earth at its departure epoch: the
    final state and the arrival's Julian date."""
    jd0 = 2451545.0 + result.epoch * TU_DAYS
    y = de421_ecliptic("earthmoon", jd0)
    ac = problem.sail.ac * result.ac_scale
    kappa = np.ones(result.alpha.size) if result.throttle is None else result.throttle
    for alpha, delta, k, dt in zip(result.alpha, result.delta, kappa, result.durations):
        y = solve_ivp(esail_rhs(ac * k, alpha, delta), (0, dt), y, method="DOP853",
                      rtol=rtol, atol=atol).y[:, -1]
    return y, jd0 + float(np.sum(result.durations)) * TU_DAYS


def test_problem_switches():
    assert mars_problem().three_d()
    assert mars_problem(planar=None).three_d()  # a real body flies in 3-D unless asked
    assert not mars_problem(planar=True).three_d()
    circle = dict(name="c", departure=eo.ParkingOrbit(a_au=1.0), sail=eo.Sail(ac_mm_s2=1.0),
                  target=eo.CircularOrbit(radius_au=1.5))
    assert not eo.Problem(**circle).three_d()
    with pytest.raises(InputError, match="planar = False needs a real body"):
        eo.Problem(**circle, planar=False)
    with pytest.raises(InputError, match=r"sail.clock_max_deg = 200 .*outside"):
        eo.Sail(ac_mm_s2=1.0, clock_max_deg=200)
    with pytest.raises(InputError, match=r"sail.clock_max_deg = -10 .*outside"):
        eo.Sail(ac_mm_s2=1.0, clock_min_deg=0, clock_max_deg=-10)
    # Free over the full circle: a box well past a turn either way of any start in
    # [-pi, pi], which is all a solve ever starts from.
    lo, hi = mars_problem().clock_bounds()
    assert lo == -hi and hi >= 3 * math.pi
    bounded = mars_problem(sail=eo.Sail(ac_mm_s2=1.0, clock_min_deg=-30, clock_max_deg=30))
    assert np.allclose(bounded.clock_bounds(), np.radians([-30, 30]), rtol=0, atol=1e-15)


def test_a_wrapped_clock_is_the_same_attitude_and_one_in_range_is_kept():
    """``wrap_clock`` takes a clock into [-pi, pi] without changing the thrust, written
    out here (the Cartesian equations' right-hand side), and keeps 180 deg as it is."""
    from esail_opt.optimisation.ipopt import wrap_clock

    rng = np.random.default_rng(7)
    deltas = np.r_[rng.uniform(-1e4, 1e4, 20), 4 * math.pi - 1e-9, -3 * math.pi]
    wrapped = wrap_clock(deltas)
    assert np.all(np.abs(wrapped) <= math.pi)
    y = np.r_[1.1, 0.2, 0.05, -0.1, 0.9, 0.03]
    for delta, back in zip(deltas, wrapped):
        assert np.allclose(esail_rhs(1e-3, 0.6, delta)(0, y), esail_rhs(1e-3, 0.6, back)(0, y),
                           rtol=0, atol=1e-15)
    assert wrap_clock([math.pi, -math.pi, 0.3]).tolist() == [math.pi, -math.pi, 0.3]


def test_a_free_clock_is_reported_by_the_attitudes_canonical_name():
    """With the clock free and the pitch bounds symmetric, the schedule names each
    attitude with its clock in (-90, 90] deg (the same sail normal as the NLP's); with
    the clock bounded by the sail, as the NLP has it."""
    from types import SimpleNamespace

    from esail_opt.app.from_run import _attitudes_deg

    result = SimpleNamespace(alpha=np.radians([30.0, 30.0, -20.0]),
                             delta=np.radians([170.0, -100.0, 40.0]))
    free = _attitudes_deg(mars_problem(), result)
    assert np.allclose(free, [(-30.0, -10.0), (-30.0, 80.0), (-20.0, 40.0)], atol=1e-12)
    bounded = mars_problem(sail=eo.Sail(ac_mm_s2=1.0, clock_min_deg=-180, clock_max_deg=179))
    assert np.allclose(_attitudes_deg(bounded, result),
                       [(30.0, 170.0), (30.0, -100.0), (-20.0, 40.0)], atol=1e-12)


@pytest.mark.slow
def test_a_solve_whose_clock_reaches_its_box_goes_on_past_it(monkeypatch):
    """The Earth-Venus minimum a_c, one of whose clocks ends near 266 deg from a start at
    0, solved with the clock's box (``problem.CLOCK_ROOM``) at 216 deg: the solve that
    pressed a clock on the box goes on from the clocks wrapped, and ends where the
    solve with the full box ends (without that, it stopped 1e-4 higher on the box)."""
    from esail_opt.optimisation import ipopt
    from esail_opt.optimisation import problem as problem_module
    from esail_opt.optimisation.problem_file import shipped_problem

    roomy = pipeline.solve(shipped_problem("earth_venus_min_ac"))
    room = 1.2 * math.pi
    monkeypatch.setattr(problem_module, "CLOCK_ROOM", room)
    monkeypatch.setattr(ipopt, "CLOCK_ROOM", room)
    taken_on = []
    off = ipopt._off_the_box
    monkeypatch.setattr(ipopt, "_off_the_box",
                        lambda tr, result: taken_on.append(off(tr, result)) or taken_on[-1])
    boxed = pipeline.solve(shipped_problem("earth_venus_min_ac"))
    assert any(w is not None for w in taken_on)
    assert roomy.verified and boxed.verified, (roomy.note, boxed.note)
    assert boxed.result.ac_scale == pytest.approx(roomy.result.ac_scale, rel=1e-6)
    assert np.all(np.abs(boxed.result.delta) <= math.pi)


@pytest.mark.slow
def test_clocks_that_hardly_move_the_flight_stay_in_their_box():
    """The throttled Earth-Mars minimum time leaving 2033-09-15 (2 mm/s^2, 12 segments,
    some coasting): unbounded, its clocks ran off to 1e8 turns and no correction of the
    error control converged again (not verified).  Boxed, it is verified by CVODES on the
    Cartesian equations, and its final schedule, flown here by DOP853 from DE421's
    Earth, meets DE421's Mars."""
    from esail_opt.optimisation import ipopt
    from esail_opt.optimisation import problem as problem_module

    problem = mars_problem(name="em2033", departure=eo.BodyDeparture(body="earth",
                                                                      date="2033-09-15"),
                           sail=eo.Sail(ac_mm_s2=2.0, throttle=True),
                           segments=eo.Segments(count=12, sub_arcs=3, equal=False))
    clocks = []  # the largest clock of each 3-D solve, rad (the projected ones have none)
    off = ipopt._off_the_box

    def spy(tr, result):
        at = ipopt._clock_slice(tr)
        if at is not None:
            clocks.append(np.max(np.abs(result.w[at])))
        return off(tr, result)

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(ipopt, "_off_the_box", spy)
        run = pipeline.solve(problem)
    assert run.verified, run.note
    assert clocks and max(clocks) <= problem_module.CLOCK_ROOM
    y, arrival = fly_schedule(problem, run.result)
    mars = de421_ecliptic("mars", arrival)
    assert np.linalg.norm(y[:3] - mars[:3]) * AU_KM < problem.tolerance.position_km


def test_the_departure_is_de421s_unprojected_earth():
    """The NLP's 3-D start (polar state in a plane) is DE421's ecliptic state."""
    problem = mars_problem()
    y = node_cartesian(np.r_[problem.plane_x0()[:4], 0.0, problem.plane_x0()[4:]])
    ref = de421_ecliptic("earthmoon", 2451545.0 + problem.epoch() * TU_DAYS)
    # 1e-12 au is 15 cm; the rotation and the units here are written independently.
    assert np.abs(y[:3] - ref[:3]).max() < 1e-12
    assert np.abs(y[3:] - ref[3:]).max() < 1e-12
    assert abs(ref[2]) > 1e-6  # the Earth-Moon barycentre is off the ecliptic
    # theta is on the branch of the planar track's unwrapped longitude (hundreds of
    # radians since 1900), within the small angle between the two planes' axes.
    from esail_opt.bodies import lookup

    track_theta = float(lookup.track("earth").polar(problem.epoch())[1])
    assert track_theta > 100
    assert abs(problem.plane_x0()[1] - track_theta) < 1e-3


@pytest.mark.parametrize("alpha_deg, delta_deg", [(35.0, 0.0), (35.0, 60.0), (-50.0, -120.0)])
def test_segment3d_against_dop853(alpha_deg, delta_deg):
    """One 3-D closed-form segment of 0.4 rad (8 second-order sub-arcs) against DOP853 on
    the Cartesian equations over the segment's own duration, from an inclined orbit:
    the second-order arcs' error over 0.05 rad at a~_c = 0.17 is well below 1e-7 au."""
    segment = closed_form_segment3d(model=ArcModel(sub_arcs=8))
    quat = np.array([math.cos(0.1), math.sin(0.1), 0.0, 0.0])  # 11.5 deg about x
    start = np.r_[1.0, 0.3, 0.05, 1.02, 0.0, quat]
    ac, alpha, delta = 1.0 / 5.930, math.radians(alpha_deg), math.radians(delta_deg)
    end = np.array(segment(start, ac, alpha, delta, 0.4)[0]).ravel()
    y0 = node_cartesian(start)
    flown = solve_ivp(esail_rhs(ac, alpha, delta), (0, end[4]), y0, method="DOP853",
                      rtol=1e-13, atol=1e-14).y[:, -1]
    y1 = node_cartesian(end)
    assert np.linalg.norm(y1[:3] - flown[:3]) < 1e-7
    assert np.linalg.norm(y1[3:] - flown[3:]) < 1e-7
    if delta_deg:
        # The plane really turned: the normal moved by more than the error above.
        h0, h1 = np.cross(y0[:3], y0[3:]), np.cross(flown[:3], flown[3:])
        assert np.linalg.norm(h0 / np.linalg.norm(h0) - h1 / np.linalg.norm(h1)) > 1e-3


def test_the_polish_segment3d_flies_the_cartesian_equations_in_the_closed_forms_gauge():
    """The 3-D polish's segment (RK4 in time, 64 steps over 0.4 TU) ends, as a node, on
    DOP853's Cartesian flight of the same duration, with theta advanced by the angle the
    Sun-sail line swept (|r x v| / r^2, integrated here with the flight).  Its plane's
    frame is the closed form's: the closed-form segment over that angle ends on the same
    node, quaternion included, to the closed form's own error (a frame spun about the
    normal, as the smallest rotation from the ecliptic's axis gives, differs by O(1))."""
    quat = np.array([math.cos(0.1), math.sin(0.1), 0.0, 0.0])  # 11.5 deg about x
    start = np.r_[1.0, 0.3, 0.05, 1.02, 0.0, quat]
    ac, alpha, delta = 1.0 / 5.930, math.radians(35.0), math.radians(60.0)
    end = np.array(rk4_time_segment3d(64)(start, ac, alpha, delta, 0.4)[0]).ravel()
    rhs = esail_rhs(ac, alpha, delta)

    def with_angle(t, z):
        return np.r_[rhs(t, z[:6]), np.linalg.norm(np.cross(z[:3], z[3:6])) / np.dot(z[:3], z[:3])]
    flown = solve_ivp(with_angle, (0, 0.4), np.r_[node_cartesian(start), start[1]],
                      method="DOP853", rtol=1e-13, atol=1e-14).y[:, -1]
    # RK4's error at 64 steps is 4e-12 here (1e-9 at 16 steps).
    assert np.abs(node_cartesian(end) - flown[:6]).max() < 1e-10
    assert abs(end[1] - flown[6]) < 1e-10 and abs(end[4] - 0.4) < 1e-14
    closed = closed_form_segment3d(model=ArcModel(sub_arcs=8))
    other = np.array(closed(start, ac, alpha, delta, end[1] - start[1])[0]).ravel()
    assert np.abs(other - end).max() < 1e-7


def test_the_compiled_polish_segment3d_is_the_virtual_machines():
    """Compiled (the RK4 step with its derivatives, the segment's chain over it), the 3-D
    polish's segment gives the expanded SX segment's end, Jacobian and Hessian of a
    weighted end, to rounding."""
    native = rk4_time_segment3d(4, native=True)
    if native.class_name() != "External":
        pytest.skip("no C compiler here: the segment stays on the virtual machine")
    plain = rk4_time_segment3d(4)
    quat = np.array([math.cos(0.1), math.sin(0.1), 0.0, 0.0])
    point = [np.r_[1.0, 0.3, 0.05, 1.02, 0.0, quat], 1.0 / 5.930, math.radians(35.0),
             math.radians(60.0), 0.4]
    weights = np.linspace(-1.0, 1.0, 9)
    x = ca.MX.sym("x", 13)
    parts = [x[:9], x[9], x[10], x[11], x[12]]

    def derivatives(segment):
        end = segment(*parts)[0]
        weighted = ca.dot(ca.DM(weights), end)
        f = ca.Function("f", [x], [end, ca.jacobian(end, x), ca.hessian(weighted, x)[0]])
        return [np.array(v) for v in f(np.r_[point[0], point[1:]])]

    for a, b in zip(derivatives(native), derivatives(plain)):
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12)


def test_node_from_swept_names_the_state_with_the_given_angle():
    """node_from_swept writes a Cartesian state as a node whose theta is the angle given:
    the node gives the state back, whatever the angle, and a node's own state with its
    own theta gives the node back (quaternion up to sign)."""
    rng = np.random.default_rng(5)
    for _ in range(5):
        quat = rng.normal(size=4)
        quat /= np.linalg.norm(quat)
        ref = np.r_[rng.uniform(0.5, 2), rng.uniform(-20, 20), rng.normal(0, 0.1),
                    rng.uniform(0.6, 1.2), quat]
        y = node_cartesian(np.r_[ref[:4], 0.0, ref[4:]])
        again = np.array(node_from_swept(y, ref[1], quat), float).ravel()
        sign = np.sign(np.dot(again[4:], ref[4:]))
        np.testing.assert_allclose(np.r_[again[:4], sign * again[4:]], ref, rtol=0, atol=1e-12)
        moved = np.array(node_from_swept(y, ref[1] + 0.3, quat), float).ravel()
        assert abs(moved[1] - ref[1] - 0.3) < 1e-15
        np.testing.assert_allclose(node_cartesian(np.r_[moved[:4], 0.0, moved[4:]]), y,
                                   rtol=0, atol=1e-12)


def test_node_near_keeps_the_state_and_the_gauge():
    """node_near writes a Cartesian state as a node in a neighbour's gauge: the node
    gives the state back, and a node's own state gives the node back."""
    rng = np.random.default_rng(3)
    for _ in range(5):
        quat = rng.normal(size=4)
        quat /= np.linalg.norm(quat)
        ref = np.r_[rng.uniform(0.5, 2), rng.uniform(-20, 20), rng.normal(0, 0.1),
                    rng.uniform(0.6, 1.2), 3.0, quat]
        again = node_near(np.r_[node_cartesian(ref), 3.0], ref)
        # The quaternion up to sign (the same rotation), everything else as it was.
        sign = np.sign(np.dot(again[5:], ref[5:]))
        np.testing.assert_allclose(np.r_[again[:5], sign * again[5:]], ref, rtol=0, atol=1e-12)
        moved = node_cartesian(ref) + rng.normal(0, 1e-3, 6)
        np.testing.assert_allclose(node_cartesian(node_near(np.r_[moved, 0.0], ref)), moved,
                                   rtol=0, atol=1e-13)


def test_seed_of_a_3d_problem_is_continuous():
    """The seed's nodes are the NLP's own 3-D segments flown from the departure."""
    problem = mars_problem()
    guess = initial_guess(problem)
    assert guess.nodes.shape == (9, 20)
    seg = ClosedForm().function(problem)
    start = np.r_[problem.plane_x0()[:4], 0.0, problem.plane_x0()[4:]]
    end = np.array(seg(start, problem.sail.ac, guess.alpha[0], 0.0, guess.lengths[0])[0]).ravel()
    assert np.abs(end - guess.nodes[:, 0]).max() < 1e-12


def test_a_lifted_planar_start_is_continuous_in_3d_and_keeps_its_flight():
    """A start of the projected problem lifted into 3-D: its nodes are the 3-D segments
    flown from the unprojected departure at the same pitches, throttles and a_c scale
    with the clock at 0, and their radius, speeds and times are the planar ones to the
    order of the Earth's height over the ecliptic (a few 1e-5 of their size)."""
    problem = mars_problem(objective=eo.MinAcceleration(tof_days=600.0))
    flat = dataclasses.replace(problem, planar=True)
    rng = np.random.default_rng(3)
    planar = dataclasses.replace(initial_guess(flat), ac_scale=0.7,
                                 throttle=rng.uniform(0.5, 1.0, 20),
                                 alpha=rng.uniform(-0.6, 0.6, 20))
    planar.nodes = flown_segments(flat, planar.alpha, planar.lengths, flat.x0(),
                                  throttle=0.7 * planar.throttle)[:, 1:]
    lifted = lifted_guess(problem, planar)
    assert lifted.nodes.shape == (9, 20) and not np.any(lifted.delta)
    np.testing.assert_array_equal(lifted.throttle, planar.throttle)
    seg = ClosedForm().function(problem)
    ac = problem.sail.ac * 0.7 * planar.throttle
    node = np.r_[problem.plane_x0()[:4], 0.0, problem.plane_x0()[4:]]
    for i in range(20):
        node = np.array(seg(node, ac[i], planar.alpha[i], 0.0, planar.lengths[i])[0]).ravel()
        assert np.abs(node - lifted.nodes[:, i]).max() < 1e-12
    rows = [0, 2, 3, 4]  # r, v_r, v_theta, t: the angle's origin is the plane's own
    np.testing.assert_allclose(lifted.nodes[rows], planar.nodes[rows], rtol=2e-4)


@pytest.mark.slow
def test_a_3d_free_date_ranked_on_the_projection_does_no_worse_than_a_3d_scan(
        monkeypatch):
    """A 3-D rendezvous with its departure free over six months: the pipeline ranks the
    dates on the projected model and lifts the best.  Its verified 3-D optimum is no
    slower than the best date of the same window scanned in 3-D (the path taken when
    the lifted start does not converge), and its schedule, flown here by DOP853 from
    DE421's Earth at the date it chose, meets DE421's unprojected Mars."""
    from esail_opt.optimisation import scan

    problem = mars_problem(departure=eo.BodyDeparture(
        body="earth", window=("2031-05-01", "2031-11-01")))
    run = pipeline.solve(problem)
    assert run.verified, run.note
    result = run.result
    y, arrival = fly_schedule(problem, result)
    mars = de421_ecliptic("mars", arrival)
    assert np.linalg.norm(y[:3] - mars[:3]) * AU_KM < problem.tolerance.position_km

    monkeypatch.setattr(scan, "_lifted_seed",
                        lambda p, progress: scan.Seed(p, None, 0, 0.0))
    scanned = scan.seed_free_date(problem)
    assert scanned.guess is not None and scanned.guess.delta is not None
    # The nodes' fifth row is the time since departure: the scanned date's time of flight.
    assert np.sum(result.durations) <= scanned.guess.nodes[4, -1] * (1 + 1e-9)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["earth_venus_min_ac", "earth_venus_min_ac_planar"])
def test_a_lone_min_ac_solve_reaches_the_class_a_scan_of_its_date_finds(name):
    """The Earth-Venus minimum a_c leaving 2031-01-21 in 720 d, in 3-D and projected: a
    lone solve's descent over the turn counts needs no more a_c than the scan of the
    same cell warm from 2031-01-01, and ends on a count both of whose neighbours it
    solved and beat.  In 3-D its schedule, flown here by DOP853 from DE421's Earth,
    meets DE421's unprojected Venus.  (Its classes' starts used to wind other counts
    than their own: the lone solves stopped at 2.356 and 2.330 mm/s^2, the scans found
    0.601 and 0.603.)"""
    from esail_opt.bodies import dates
    from esail_opt.optimisation import scan
    from esail_opt.optimisation.problem_file import shipped_problem

    problem = shipped_problem(name)
    cells = [scan.at_date(problem, dates.jd_from_iso(d), 720.0)
             for d in ("2031-01-01", "2031-01-21")]
    scanned = scan.scan(cells)[1]
    assert scanned.verified, scanned.note
    run = pipeline.solve(cells[1])
    assert run.verified, run.note
    lone, by_scan = run.result.ac_scale, scanned.result.ac_scale
    assert lone <= by_scan * (1 + 1e-3), (lone, by_scan)
    chosen = run.result.revolutions_k
    # The counts it found a point in (on either model), and the a_c of those solved in
    # the problem's own model (a 3-D run lifts only the best of its projected counts).
    looked = {c.revolutions_k for c in run.classes if c.ac_scale is not None}
    solved = [c.ac_scale for c in run.classes if c.ac_scale is not None and not c.projected]
    assert {chosen - 1, chosen + 1} <= looked and min(solved) == lone
    if problem.three_d():
        y, arrival = fly_schedule(problem, run.result)
        venus = de421_ecliptic("venus", arrival)
        assert np.linalg.norm(y[:3] - venus[:3]) * AU_KM < problem.tolerance.position_km


@pytest.mark.slow
def test_a_count_with_no_point_does_not_end_the_turn_count_search():
    """Earth-Venus minimum time in 3-D on 10 segments, leaving 2033-05-20 at 0.8 mm/s^2:
    the count beside the first one found ends infeasible, and the one beyond it is the
    fastest.  A lone solve steps over the count with no point (it used to stop there,
    at 1,098 d against 455 d): its answer is no slower than a probe of any count from
    k = -23 to -19 made here, and its schedule, flown here by DOP853 from DE421's Earth,
    meets DE421's unprojected Venus."""

    problem = eo.Problem(name="venus10", departure=eo.BodyDeparture(body="earth",
                                                                    date="2033-05-20"),
                         sail=eo.Sail(ac_mm_s2=0.8), segments=eo.Segments(count=10, sub_arcs=2),
                         objective=eo.MinTime(), target=eo.BodyRendezvous(body="venus"))
    run = pipeline.solve(problem)
    assert run.verified, run.note
    tof = float(np.sum(run.result.durations))
    probed = []
    for k in range(-23, -18):
        other, _, _ = multistart.probe_rendezvous_class(problem, k, 3000)
        if other.outcome.found:
            probed.append(float(np.sum(other.durations)))
    assert probed and tof <= min(probed) * (1 + 1e-4), (tof, probed)
    assert any(c.constraint_violation > 1e-6 and c.tof is None for c in run.classes)
    y, arrival = fly_schedule(problem, run.result)
    venus = de421_ecliptic("venus", arrival)
    assert np.linalg.norm(y[:3] - venus[:3]) * AU_KM < problem.tolerance.position_km


@pytest.mark.slow
def test_turn_counts_searched_on_the_projection_choose_what_the_3d_search_chooses():
    """Earth-Venus minimum a_c in 3-D: the turn counts searched on the projected model,
    only the best of them lifted into 3-D, give the class and the a_c of the search that
    solves every count it looks at in 3-D (``pipeline._solved``, the route a 3-D run
    takes when the projection cannot rank its classes).  Each class left on the
    projection says so and needed more than LIFT_RATIO times the answer's objective
    there, and the answer's schedule, flown here by DOP853 from DE421's Earth, meets
    DE421's unprojected Venus."""
    from esail_opt.optimisation.problem_file import shipped_problem

    problem = shipped_problem("earth_venus_min_ac")
    run = pipeline.solve(problem)
    in_3d = pipeline._solved(problem, lambda text: None)
    assert run.verified and in_3d.verified, (run.note, in_3d.note)
    assert run.result.revolutions_k == in_3d.result.revolutions_k
    assert run.result.ac_scale <= in_3d.result.ac_scale * (1 + 1e-6), (
        run.result.ac_scale, in_3d.result.ac_scale)
    left = [c for c in run.classes if c.projected and c.objective is not None]
    assert left and all("projected model" in c.label for c in left)
    lifted = {c.revolutions_k for c in run.classes if not c.projected}
    # Not lifted: far worse on the projection, or a count already lifted from its best
    # projected start.
    assert all(c.objective > multistart.LIFT_RATIO * run.result.objective
               or c.revolutions_k in lifted for c in left)
    assert not any(c.projected for c in in_3d.classes if c.objective is not None)
    y, arrival = fly_schedule(problem, run.result)
    venus = de421_ecliptic("venus", arrival)
    assert np.linalg.norm(y[:3] - venus[:3]) * AU_KM < problem.tolerance.position_km


@pytest.mark.slow
def test_a_class_the_projection_leaves_undecided_sends_the_search_into_3d():
    """Earth-Bennu minimum time (6 deg of plane change): on the projected model the
    count k = 5 ends undecided at its cap, so the projection cannot rank the classes,
    and the search runs in 3-D, where k = 5 is the fastest by far.  Ranked on the
    projection alone, the answer would be its best class, k = 6 (about 865 d); the 3-D
    run, with every class it found solved in 3-D, takes less than 0.6 of that."""
    from esail_opt.optimisation.problem_file import shipped_problem

    problem = shipped_problem("earth_bennu_rendezvous")
    run = pipeline.solve(problem)
    projected = pipeline.solve(dataclasses.replace(problem, planar=True))
    assert run.verified and projected.verified, (run.note, projected.note)
    assert not any(c.projected for c in run.classes if c.objective is not None)
    assert any(c.revolutions_k == 5 and c.tof is None for c in projected.classes)
    tof, projected_tof = (float(np.sum(r.result.durations)) for r in (run, projected))
    assert tof < 0.6 * projected_tof, (tof, projected_tof)


def read_oem_states(text):
    """The data lines of a KVN OEM: epochs (str) and states (6, N) in km and km/s."""
    rows = [line.split() for line in text.splitlines()
            if line[:4].isdigit() and len(line.split()) == 7]
    return [r[0] for r in rows], np.array([[float(v) for v in r[1:]] for r in rows]).T


@pytest.mark.slow
def test_mars_rendezvous_in_3d_flies_onto_de421s_mars(tmp_path):
    """Done-when of the 3-D optimisation: a fixed-date 3-D Earth-Mars rendezvous, its
    schedule (pitch, clock and duration per segment) flown here by DOP853 at rtol 1e-12
    on the Cartesian equations from DE421's Earth, meets DE421's unprojected Mars at the
    arrival date within the default tolerance (10,000 km, 10 m/s)."""
    problem = mars_problem()
    run = pipeline.solve(problem)
    assert run.verified, run.note
    result = run.result
    assert result.delta is not None
    jd0 = 2451545.0 + result.epoch * TU_DAYS
    y, arrival = fly_schedule(problem, result)
    mars = de421_ecliptic("mars", arrival)
    miss_km = np.linalg.norm(y[:3] - mars[:3]) * AU_KM
    miss_m_s = np.linalg.norm(y[3:] - mars[3:]) * AU_KM * 1e3 / (TU_DAYS * 86400)
    assert miss_km < problem.tolerance.position_km
    assert miss_m_s < problem.tolerance.velocity_m_s
    # Mars is 1.85 deg out of the ecliptic: the flight ends well off it, as Mars does.
    assert abs(y[2]) * AU_KM > 1e5
    # The files: schema 7, the clock in schedule.csv, the departure state as DE421's Earth,
    # the bodies' distances from the ecliptic and the flight's along its normal, and the
    # OEM's last state (ICRF, km) on DE421's Mars (rotated back here).
    import csv
    import json

    from esail_opt.app.solution import Solution

    Solution.of(run).write(tmp_path, plots=False)
    data = json.loads((tmp_path / "solution.json").read_text())
    assert data["schema_version"] == schema.SCHEMA_VERSION
    # ISO 8601 cannot name the dates' scale: the file does, beside them.
    assert data["time_scale"] == "TDB" and data["departure_date"].startswith("20")
    dep = data["problem"]["departure_state"]
    earth = de421_ecliptic("earthmoon", jd0)
    assert abs(dep["z_au"] - earth[2]) < 1e-12 and abs(dep["x_au"] - earth[0]) < 1e-12
    assert data["departure_body"]["out_of_plane_km"] == pytest.approx(abs(earth[2]) * AU_KM,
                                                                      rel=1e-9)
    body = data["target_body"]
    assert body["out_of_plane_km"] == pytest.approx(abs(mars[2]) * AU_KM, rel=1e-9)
    # The verifier's flight and this one end within a few km of each other.
    assert abs(body["normal_miss_km"] - abs(y[2] - mars[2]) * AU_KM) < 10.0
    assert data["verification"]["normal_miss_km"] == body["normal_miss_km"]
    rows = list(csv.DictReader((tmp_path / "schedule.csv").open()))
    assert len(rows) == result.alpha.size
    # Each row names the NLP's sail: its normal, in (r_hat, t_hat, h_hat), is the same
    # line (the row may give the other of the attitude's two names).
    def normal(alpha, delta):
        return np.array([np.cos(alpha), np.sin(alpha) * np.cos(delta),
                         np.sin(alpha) * np.sin(delta)])

    for r, alpha, delta in zip(rows, result.alpha, result.delta):
        row_normal = normal(math.radians(float(r["alpha_deg"])),
                            math.radians(float(r["clock_deg"])))
        assert np.linalg.norm(np.cross(row_normal, normal(alpha, delta))) < 1e-12
    incl = data["trajectory"]["cvodes"]["inclination_deg"]
    assert incl[0] < 0.01 and abs(incl[-1] - 1.85) < 0.05  # Earth's plane to Mars's
    epochs, states = read_oem_states((tmp_path / "trajectory.oem").read_text())
    c, s = math.cos(EPS), math.sin(EPS)
    to_icrf = np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    mars_icrf = to_icrf @ mars[:3] * AU_KM
    assert epochs[-1].startswith(data["arrival_date"][:16])
    assert np.linalg.norm(states[:3, -1] - mars_icrf) < problem.tolerance.position_km


@pytest.mark.slow
def test_a_polished_3d_mars_rendezvous_meets_de421s_mars_to_a_metre():
    """The 3-D polish, on the fixed-date Earth-Mars minimum a_c (657 d, throttle free):
    the polished schedule (pitch, clock, throttle and duration per segment), flown here
    by DOP853 at rtol 1e-13 on the Cartesian equations from DE421's Earth at the
    departure epoch, meets DE421's unprojected Mars at the arrival within the polish's
    1 m and 1 mm/s, and the polished NLP's final node agrees with that flight to the
    same bounds."""
    problem = mars_problem(departure=eo.BodyDeparture(body="earth",
                                                      date="2031-08-11T12:18:59.938"),
                           segments=eo.Segments(count=40),
                           objective=eo.MinAcceleration(tof_days=657.0191))
    run = pipeline.solve(problem, polish=True)
    assert run.polish.verified, run.polish.note
    exact = run.polish.result
    assert exact.delta is not None and np.ptp(exact.delta) > 0.1  # the clock is used
    y, arrival = fly_schedule(problem, exact, rtol=1e-13, atol=1e-15)
    mars = de421_ecliptic("mars", arrival)
    to_m_s = AU_KM * 1e3 / (TU_DAYS * 86400)
    assert np.linalg.norm(y[:3] - mars[:3]) * AU_KM < 1e-3
    assert np.linalg.norm(y[3:] - mars[3:]) * to_m_s < 1e-3
    node = node_cartesian(exact.nodes[:, -1])
    assert np.linalg.norm(y[:3] - node[:3]) * AU_KM < 1e-3
    assert np.linalg.norm(y[3:] - node[3:]) * to_m_s < 1e-3


@pytest.mark.slow
def test_a_polished_941_day_3d_rendezvous_is_verified_and_meets_de421s_mars():
    """A long 3-D polish can be judged to a metre: the minimum-time Earth-Mars rendezvous
    at 1.5 mm/s^2 leaving 2033-03-01 (941 d, two and a half turns) is polished and
    verified, and its schedule, flown here from DE421's Earth by DOP853 at rtol 2.3e-14
    on the turning plane's equations (``test_rectified3d.fly_turning_dop853``: on the
    Cartesian equations DOP853 itself strays by decimetres over such a flight), meets
    DE421's unprojected Mars within the polish's 1 m and 1 mm/s."""
    problem = mars_problem(departure=eo.BodyDeparture(body="earth", date="2033-03-01"),
                           sail=eo.Sail(ac_mm_s2=1.5),
                           segments=eo.Segments(count=30, sub_arcs=3, equal=False))
    run = pipeline.solve(problem, polish=True)
    assert run.polish.verified, run.polish.note
    exact = run.polish.result
    assert exact.throttle is None or np.all(exact.throttle == 1)  # full thrust throughout
    tof = float(np.sum(exact.durations))
    assert tof * TU_DAYS > 900
    jd0 = 2451545.0 + exact.epoch * TU_DAYS
    y = fly_turning_dop853(de421_ecliptic("earthmoon", jd0), problem.sail.ac * exact.ac_scale,
                           exact.alpha, exact.delta, exact.durations, rtol=2.3e-14)
    mars = de421_ecliptic("mars", jd0 + tof * TU_DAYS)
    assert np.linalg.norm(y[:3] - mars[:3]) * AU_KM < 1e-3
    assert np.linalg.norm(y[3:] - mars[3:]) * AU_KM * 1e3 / (TU_DAYS * 86400) < 1e-3


def test_a_per_revolution_mesh_follows_the_turns_its_optimum_flies():
    """``Segments(per_revolution=10)`` is counted on the seed's angle, about half a turn
    to Laurel: the delivered flight used to have 10 segments over the 2.49 turns it
    flew, 4 a turn (1778.7 d; 1520.0 d on 40 segments).  Each optimum that flies more
    turns than its mesh was counted for is solved again on a finer one, so the
    delivered flight has at least 10 a turn of its own, less the slack allowed."""
    from conftest import USER_PROBLEMS
    from esail_opt.optimisation.problem_file import load_problem

    run = pipeline.solve(load_problem(USER_PROBLEMS / "earth_laurel_per_revolution.py"))
    assert run.verified, run.note
    turns = float(np.sum(run.result.lengths)) / (2 * math.pi)
    assert run.result.alpha.size >= 10 * turns / error_control.DENSITY_SLACK
    assert turns > 1  # the seed's half turn would not have asked for this mesh


@pytest.mark.parametrize("turns", [-21, 3])
def test_cylindrical_target_rows_are_the_cartesian_miss(turns):
    """The 3-D rendezvous rows (``cylindrical_constraints``) at a state 2,000 km and
    1 m/s off Venus's track: rebuilding the sail's Cartesian state from the body's
    track plus the rows (numpy's cos and sin, here) gives that state back, and at the
    body's own state on the row's turn they vanish."""
    import casadi as ca

    from esail_opt.bodies import lookup
    from esail_opt.physics.constants import length_to_km

    target, t0, tf = eo.BodyRendezvous(body="venus"), 11.0, 10.0
    body = np.array(lookup.track3("venus").function(t0 + tf)).ravel()
    lam_b = float(lookup.track("venus").polar(t0 + tf)[1])
    off = np.r_[np.array([1200.0, -1500.0, 400.0]) / AU_KM, np.array([0.6, 0.3, -0.74]) * 1e-3
                * TU_DAYS * 86400 / (AU_KM * 1e3)]

    def rows(y, theta):
        return np.array(ca.vertcat(*target.cylindrical_constraints(
            ca.DM(y), theta + 2 * math.pi * turns, tf, turns, t0))).ravel()

    assert np.abs(rows(body, lam_b)).max() < 1e-13
    y = body + off
    got = rows(y, lam_b + 0.01)  # the sail's own plane angle is off the longitude a little
    rho_b, z_b = math.hypot(body[0], body[1]), body[2]
    lam = lam_b + got[1]
    rho = rho_b + got[0]
    pos = np.array([rho * math.cos(lam), rho * math.sin(lam), z_b + got[2]])
    # A longitude of 21 turns carries 3e-14 rad of rounding: 3e-6 km at 0.7 au, and
    # 4e-14 of the speed (about 1 au/TU).
    assert length_to_km(np.linalg.norm(pos - y[:3])) < 1e-5
    v_rho_b = (body[0] * body[3] + body[1] * body[4]) / rho_b
    v_lam_b = (body[0] * body[4] - body[1] * body[3]) / rho_b
    v_rho, v_lam = v_rho_b + got[3], v_lam_b + got[4]
    vel = np.array([v_rho * math.cos(lam) - v_lam * math.sin(lam),
                    v_rho * math.sin(lam) + v_lam * math.cos(lam), body[5] + got[5]])
    assert np.abs(vel - y[3:]).max() < 1e-13
