"""The 3-D rectified closed form (``propagation.rectified3d``, ``batch.propagate_batch3d``)
against CVODES flights in three dimensions (``simulate.simulate3d``, in the turning plane
and on the Cartesian equations), themselves checked here against DOP853 on the Cartesian
equations written out in ``test_plane_turn`` and on the turning plane's equations written
out below, and RK4 on them (``rk4.rk4_segment3d``)."""

import math

import casadi as ca
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from esail_opt.physics import rotation
from esail_opt.physics.constants import accel_from_mm_s2, length_to_km, time_from_days
from esail_opt.physics.elements import cartesian_from_polar3d, polar_from_classical
from esail_opt.propagation.arcs import FIRST_ORDER, ArcModel
from esail_opt.propagation.batch import propagate_batch3d
from esail_opt.propagation.rectified import propagate
from esail_opt.propagation.rectified3d import (cartesian_states, end_function3d,
                                              panel_function3d, propagate3d,
                                              rectified3d_function)
from esail_opt.propagation.rk4 import rk4_segment3d, rk4_segment_turning
from esail_opt.propagation.simulate import (FORMS_3D, VERIFY_TOLERANCE, fly_segments3d,
                                            simulate, simulate3d)
from test_plane_turn import fly_cartesian_theta

AC = accel_from_mm_s2(1.0)
X0 = np.array(polar_from_classical(1.0, 0.1, 0.5, 1.0)).ravel()
PLANE = np.array(rotation.from_rotation_vector([0.03, -0.05, 0.4])).ravel()
#: Six segments of one radian at 1 mm/s^2, clocks on both sides of the plane.
ALPHAS = np.radians([40, 35, 50, -20, 45, 30])
DELTAS = np.radians([30, -60, 90, 120, -30, 10])
LENGTHS = np.full(6, 1.0)


def cartesian(xs, column=-1):
    """The Cartesian state of one column, converted column by column; it is also
    ``cartesian_states``'s (checked in ``test_cartesian_states_column_by_column``)."""
    return np.array(cartesian_from_polar3d(xs[:4, column], xs[5:, column])).ravel()


def test_cartesian_states_column_by_column():
    xs = propagate3d(X0, PLANE, ALPHAS, DELTAS, LENGTHS, AC, samples=3)[0]
    whole = cartesian_states(xs)
    for k in range(xs.shape[1]):
        assert np.abs(whole[:6, k] - cartesian(xs, k)).max() < 1e-15
    assert np.abs(whole[6] - xs[4]).max() == 0


def reference(form="turning"):
    """The schedule flown by CVODES in ``form`` (lengths: angles the Sun-sail line sweeps)."""
    y0 = np.array(cartesian_from_polar3d(X0, PLANE)).ravel()
    return simulate3d(y0, ALPHAS, DELTAS, LENGTHS, AC, length_in="theta",
                      tol=VERIFY_TOLERANCE, form=form)


@pytest.mark.parametrize("form", FORMS_3D)
def test_cvodes_3d_is_dop853_on_the_cartesian_equations(form):
    """simulate3d in theta, in either form, ends where DOP853 on the Cartesian equations
    (written out in the tests with Huo's geometry) does, segment after segment."""
    ref = reference(form)
    y = ref[:6, 0]
    for k, (alpha, delta, length) in enumerate(zip(ALPHAS, DELTAS, LENGTHS)):
        y = fly_cartesian_theta(y, AC, alpha, delta, length)
        assert np.abs(y - ref[:6, k + 1]).max() < 1e-10


def fly_turning_dop853(y0, ac, alphas, deltas, durations, rtol):
    """A schedule flown in time by DOP853 on the turning plane's equations, written out
    here with the plane's frame carried as two unit vectors (e1, e2) rather than a
    quaternion: Eqs. 1-2 for (r, theta, v_r, v_theta), and the frame turning at
    (r f_N / h) r_hat, with Huo's thrust a = (a_c/2r)[(1 + cos^2 a) r_hat + cos a sin a
    (cos d t_hat + sin d h_hat)].  Returns the final Cartesian state."""
    pos, vel = np.asarray(y0[:3], float), np.asarray(y0[3:6], float)
    r = np.linalg.norm(pos)
    h_hat = np.cross(pos, vel) / np.linalg.norm(np.cross(pos, vel))
    z = np.r_[r, 0.0, pos @ vel / r, np.linalg.norm(np.cross(pos, vel)) / r,
              pos / r, np.cross(h_hat, pos / r)]
    for alpha, delta, duration in zip(alphas, deltas, durations):
        c, s = math.cos(alpha), math.sin(alpha)
        force = 0.5 * ac * np.array([1 + c * c, c * s * math.cos(delta),
                                     c * s * math.sin(delta)])

        def rates(_, z, force=force):
            r, theta, vr, vt = z[:4]
            fr, ft, fn = force / r
            omega = fn / vt * (math.cos(theta) * z[4:7] + math.sin(theta) * z[7:10])
            return np.r_[vr, vt / r, vt**2 / r - 1 / r**2 + fr, -vr * vt / r + ft,
                         np.cross(omega, z[4:7]), np.cross(omega, z[7:10])]

        z = solve_ivp(rates, (0, duration), z, method="DOP853", rtol=rtol,
                      atol=1e-17).y[:, -1]
    r, theta, vr, vt = z[:4]
    r_hat = math.cos(theta) * z[4:7] + math.sin(theta) * z[7:10]
    t_hat = -math.sin(theta) * z[4:7] + math.cos(theta) * z[7:10]
    return np.r_[r * r_hat, vr * r_hat + vt * t_hat]


def test_a_930_day_3d_flight_is_resolved_well_within_a_metre():
    """The verifier's flight of 30 month-long segments at 1 mm/s^2, pitch and clock
    changing at every segment, ends within half a metre of DOP853 on the turning plane's
    equations written out here, itself within centimetres of its own flight at a looser
    tolerance: a polish's 1 m bound can be judged over a long 3-D flight."""
    y0 = np.array(cartesian_from_polar3d(X0, PLANE)).ravel()
    k = np.arange(30)
    alphas = np.radians(np.where(k < 15, 35.0, -35.0))
    deltas = np.radians(60 * np.cos(0.7 * k))
    durations = np.full(30, time_from_days(31.0))
    ref = fly_turning_dop853(y0, AC, alphas, deltas, durations, rtol=2.3e-14)
    looser = fly_turning_dop853(y0, AC, alphas, deltas, durations, rtol=1e-13)
    assert length_to_km(np.linalg.norm(ref[:3] - looser[:3])) < 5e-5
    flown = simulate3d(y0, alphas, deltas, durations, AC, tol=VERIFY_TOLERANCE)[:6, -1]
    assert length_to_km(np.linalg.norm(flown[:3] - ref[:3])) < 5e-4


@pytest.mark.parametrize("form", FORMS_3D)
def test_cvodes_3d_in_time_in_the_plane_is_eqs_1_2(form):
    """In the fixed x-y plane at delta = 0, the 3-D flight in time is the polar flight of
    Eqs. 1-2 (``simulate.simulate``)."""
    x0 = np.array([1.0, 0.2, 0.05, 0.98])
    durations = [2.0, 3.0, 1.5]
    polar = simulate(x0, ALPHAS[:3], durations, AC, tol=VERIFY_TOLERANCE)
    y0 = np.array(cartesian_from_polar3d(x0, rotation.IDENTITY)).ravel()
    cart = simulate3d(y0, ALPHAS[:3], np.zeros(3), durations, AC, tol=VERIFY_TOLERANCE,
                      form=form)
    for k in range(4):
        want = np.array(cartesian_from_polar3d(polar[:4, k], rotation.IDENTITY)).ravel()
        assert np.abs(cart[:6, k] - want).max() < 1e-11
    assert np.abs(cart[6] - polar[4]).max() < 1e-12


@pytest.mark.parametrize("model", [ArcModel(), ArcModel(sub_arcs=3, native=False),
                                   FIRST_ORDER, ArcModel(order=1, sub_arcs=2)])
def test_zero_clock_is_the_planar_rectified_form(model):
    """At delta = 0 the plane does not turn and the polar rows are rectified.propagate's."""
    x0 = [1.0, 0.3, 0.01, 1.02]
    xs, q3 = propagate3d(x0, PLANE, [0.5, -0.3], [0.0, 0.0], [2.0, 1.5], 0.1, samples=3,
                         model=model)
    flat, flat_q3 = propagate(x0, [0.5, -0.3], [2.0, 1.5], 0.1, samples=3, model=model)
    assert np.abs(xs[:5] - flat).max() < 1e-13
    assert np.abs(q3 - flat_q3).max() < 1e-13
    assert np.abs(xs[5:] - PLANE[:, None]).max() == 0


def _errors(order, sub_arcs, ref):
    xs, _ = propagate3d(X0, PLANE, ALPHAS, DELTAS, LENGTHS, AC,
                        model=ArcModel(order=order, sub_arcs=sub_arcs, native=False))
    y = cartesian(xs)
    normal = np.array(rotation.matrix(xs[5:, -1]))[:, 2]
    h = np.cross(ref[:3, -1], ref[3:6, -1])
    return np.linalg.norm(y[:3] - ref[:3, -1]), np.linalg.norm(normal - h / np.linalg.norm(h))


def test_rectified_3d_converges_to_cartesian_cvodes():
    """Over six segments with clock angles (the flight leaves the start plane by 0.2 au),
    the closed form's final position and plane converge to the Cartesian flight's as the
    sub-arcs double: like 1/N at first order and like 1/N^2 at second order."""
    ref = reference()
    assert abs(ref[2, -1]) > 0.1
    counts = [8, 16, 32]
    for order, least_ratio, finest in ((1, 1.5, 1e-2), (2, 2.8, 2e-5)):
        errs = np.array([_errors(order, n, ref) for n in counts])
        assert np.all(errs[:-1, 0] / errs[1:, 0] > least_ratio)
        assert np.all(errs[:-1, 1] / errs[1:, 1] > least_ratio)
        assert errs[-1, 0] < finest
        if order == 2:
            # The last doubling is near the asymptotic 4 of a second-order chain.
            assert errs[-2, 0] / errs[-1, 0] > 3.4


@pytest.mark.parametrize("length_in", ["theta", "time"])
def test_batch_3d_is_the_single_case(length_in):
    starts = np.array([X0, [1.2, 0.0, 0.0, 0.9]])
    planes = np.array([PLANE, rotation.IDENTITY])
    alphas = np.array([ALPHAS[:3], ALPHAS[3:]])
    deltas = np.array([DELTAS[:3], DELTAS[3:]])
    lengths = np.array([[1.0, 2.0, 0.5], [0.3, 0.4, 2.0]])
    acs = [AC, 0.5 * AC]
    xs, q3 = propagate_batch3d(starts, planes, alphas, deltas, lengths, acs, samples=2,
                               length_in=length_in)
    for m in range(2):
        one, one_q3 = propagate3d(starts[m], planes[m], alphas[m], deltas[m], lengths[m],
                                  acs[m], samples=2, length_in=length_in)
        assert np.abs(xs[m] - one).max() < 1e-14
        assert np.abs(q3[m] - one_q3).max() < 1e-14


@pytest.mark.parametrize("length_in", ["theta", "time"])
def test_rk4_3d_is_fourth_order_against_cvodes(length_in):
    alpha, delta, length = math.radians(40), math.radians(50), 2.0
    y0 = np.r_[np.array(cartesian_from_polar3d(X0, PLANE)).ravel(), 0.0]
    ref = simulate3d(y0[:6], [alpha], [delta], [length], AC, length_in=length_in,
                     tol=VERIFY_TOLERANCE)[:, -1]
    errs = [np.abs(np.array(rk4_segment3d(n, length_in=length_in)(
        y0, AC, alpha, delta, length)[0]).ravel() - ref).max() for n in (10, 20, 40)]
    assert errs[-1] < 1e-6
    for coarse, fine in zip(errs, errs[1:]):
        assert 12 < coarse / fine < 20


def test_rk4_on_the_turning_plane_is_fourth_order_against_cartesian_cvodes():
    """RK4 on the polar state and the plane's quaternion ends, in Cartesian terms, where
    CVODES on the Cartesian equations does, its error falling as the steps' fourth power."""
    alpha, delta, length = math.radians(40), math.radians(50), 2.0
    y0 = np.array(cartesian_from_polar3d(X0, PLANE)).ravel()
    ref = simulate3d(y0, [alpha], [delta], [length], AC, length_in="theta",
                     tol=VERIFY_TOLERANCE)[:, -1]
    start = np.r_[X0, 0.0, PLANE]
    errs = []
    for n in (10, 20, 40):
        end = np.array(rk4_segment_turning(n)(start, AC, alpha, delta, length)[0]).ravel()
        flown = np.r_[cartesian(end[:, None]), end[4]]
        errs.append(np.abs(flown - ref).max())
    assert errs[-1] < 1e-6
    for coarse, fine in zip(errs, errs[1:]):
        assert 12 < coarse / fine < 20


@pytest.mark.parametrize("order", [1, 2])
def test_arc_derivatives_are_finite_on_circles_and_without_turn(order):
    """The NLP differentiates the arc twice: its Jacobian and Hessian stay finite at a
    circular start (e0 = 0) and at delta = 0 (no turn), where the rotation's exponential
    and the closed form have removable singularities; and the Jacobian matches central
    differences."""
    x, p = ca.SX.sym("x", 9), ca.SX.sym("p", 4)
    if order == 1:
        out = panel_function3d()(x, p[0], p[1], p[2], 0, p[3])[0]
    else:
        out = end_function3d()(x, p[0], p[1], p[2], p[3])[0]
    z = ca.vertcat(x, p)
    value = ca.Function("v", [z], [out])
    jac = ca.Function("j", [z], [ca.jacobian(out, z)])
    hess = ca.Function("h", [z], [ca.hessian(ca.sum1(out), z)[0]])
    circle = [1, 0.3, 0, 1, 0, *rotation.IDENTITY]
    for point in ([*circle, 0.1, 0.5, 0.0, 0.8], [*circle, 0.1, 0.5, 0.4, 0.8]):
        point = np.array(point, float)
        j = np.array(jac(point))
        assert np.isfinite(j).all() and np.isfinite(np.array(hess(point))).all()
        step = 1e-6
        for k in range(point.size):
            dp = np.zeros(point.size)
            dp[k] = step
            fd = (np.array(value(point + dp)) - np.array(value(point - dp))).ravel() / (2 * step)
            assert np.abs(fd - j[:, k]).max() < 1e-7


@pytest.mark.parametrize("form", FORMS_3D)
def test_segments_flown_apart_are_the_chain(form):
    """fly_segments3d from the chained flight's own segment starts gives its ends."""
    ref = reference(form)
    ends = fly_segments3d(ref[:, :-1], np.full(6, AC), ALPHAS, DELTAS, LENGTHS,
                          length_in="theta", tol=VERIFY_TOLERANCE, form=form)
    assert np.abs(ends - ref[:, 1:]).max() < 1e-12


@pytest.mark.parametrize("order", [1, 2])
def test_compiled_arcs_are_the_virtual_machines(order):
    """model.native changes the speed, not the numbers: the schedule's states and the
    segment's Jacobian agree with the virtual machine's to rounding."""
    fast, slow = (ArcModel(order=order, sub_arcs=3, native=flag) for flag in (True, False))
    a = propagate3d(X0, PLANE, ALPHAS, DELTAS, LENGTHS, AC, samples=2, model=fast)[0]
    b = propagate3d(X0, PLANE, ALPHAS, DELTAS, LENGTHS, AC, samples=2, model=slow)[0]
    assert np.abs(a - b).max() < 1e-13
    z = ca.MX.sym("z", 13)
    jacs = []
    for model in (fast, slow):
        out = rectified3d_function(1, model=model)(z[:9], z[9], z[10], z[11], z[12])[0]
        jacs.append(np.array(ca.Function("j", [z], [ca.jacobian(out, z)])(
            np.r_[X0, 0.0, PLANE, AC, ALPHAS[0], DELTAS[0], 1.0])))
    assert np.abs(jacs[0] - jacs[1]).max() < 1e-12


def test_timed_3d_arcs_converge_to_cartesian_cvodes_in_time():
    """Segments given as durations end at the asked time and converge to Cartesian
    CVODES flown in time: like 1/N at first order, like 1/N^2 at second order."""
    durations = np.full(6, 1.0)
    y0 = np.array(cartesian_from_polar3d(X0, PLANE)).ravel()
    ref = simulate3d(y0, ALPHAS, DELTAS, durations, AC, tol=VERIFY_TOLERANCE)
    for order, least_ratio in ((1, 1.6), (2, 3.0)):
        errs = []
        for n in (4, 8, 16):
            xs, _ = propagate3d(X0, PLANE, ALPHAS, DELTAS, durations, AC, length_in="time",
                                model=ArcModel(order=order, sub_arcs=n, native=False))
            end = cartesian_states(xs)[:, -1]
            assert abs(end[6] - ref[6, -1]) < 1e-12
            errs.append(np.linalg.norm(end[:3] - ref[:3, -1]))
        assert errs[0] / errs[1] > least_ratio and errs[1] / errs[2] > least_ratio
    assert errs[-1] < 3e-6


@pytest.mark.parametrize("model", [ArcModel(native=False),
                                   ArcModel(order=1, sub_arcs=2, native=False)])
def test_timed_zero_clock_is_the_planar_timed_form(model):
    x0 = [1.0, 0.3, 0.01, 1.02]
    xs, _ = propagate3d(x0, PLANE, [0.5, -0.3], [0.0, 0.0], [2.0, 1.5], 0.1, samples=2,
                        length_in="time", model=model)
    flat, _ = propagate(x0, [0.5, -0.3], [2.0, 1.5], 0.1, samples=2, length_in="time",
                        model=model)
    assert np.abs(xs[:5] - flat).max() < 1e-13
    assert np.abs(xs[5:] - PLANE[:, None]).max() == 0
