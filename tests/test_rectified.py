"""The rectified closed-form propagator against the physics core (one arc, no
rectification) and against CVODES on the paper's 10-year orbit raising (Figs. 5-7)."""

import dataclasses
import math

import casadi as ca
import numpy as np
import pytest
from scipy.optimize import brentq

from esail_opt.physics.closed_form import arc_end, arc_frame, arc_state
from esail_opt.physics.constants import accel_from_mm_s2, time_from_years
from esail_opt.physics.thrust import radial_transverse
from esail_opt.physics.elements import classical_from_polar
from esail_opt.propagation.arcs import FIRST_ORDER
from esail_opt.propagation.rectified import kepler_angle, propagate, timed_arc_function
from esail_opt.propagation.simulate import simulate

AC = accel_from_mm_s2(0.1)
ALPHA = math.radians(45)
YEARS = 10.0
ARCS = 20  # one rectification every six months: 19 rectifications, 20 arcs
CIRCLE = np.array([1.0, 0.0, 0.0, 1.0])
#: Samples per arc for the comparisons: a quarter of an arc is ~45 deg at 1 au,
#: fine enough to catch the largest radial deviation within a few per mille of it.
SAMPLES = 4
#: What this file tests: the paper's rectification, one first-order arc a segment.
PLAIN = FIRST_ORDER
RICHARDSON = dataclasses.replace(FIRST_ORDER, extrapolate=True)


def six_month_arcs(arcs=ARCS):
    return np.full(arcs, time_from_years(YEARS) / arcs)


def cvodes_at_same_times(xs, alphas, samples):
    """CVODES at the propagator's own sample times.

    The propagator's samples are equally spaced in theta within each arc, not in
    time; every sample interval is flown as its own CVODES segment of the same
    duration (with the pitch of its arc), so both trajectories are compared at
    identical times.
    """
    return simulate(CIRCLE, np.repeat(alphas, samples), np.diff(xs[4]), AC)


# -- against the physics core -------------------------------------------------------

ONE_ARC_CASES = [  # (x0, alpha_deg, dtheta)
    (CIRCLE, 45.0, 2.5),
    (np.array([1.3, 0.7, 0.12, 0.95]), -30.0, 7.0),  # eccentric, theta0 != 0, > 1 rev
    (np.array([0.6, -2.0, -0.2, 1.4]), 80.0, 0.4),
]


@pytest.mark.parametrize("x0, alpha_deg, dtheta", ONE_ARC_CASES)
def test_one_segment_is_the_plain_closed_form(x0, alpha_deg, dtheta):
    alpha = math.radians(alpha_deg)
    R, T = (float(v) for v in radial_transverse(alpha))
    xs, q3 = propagate(x0, [alpha], [dtheta], AC, samples=4, model=PLAIN)
    # arc_end with 4 panels is the same quadrature as 4 samples of one segment.
    end, dt, q3_end = (np.array(v, float).ravel() for v in arc_end(x0, dtheta, AC, R, T, panels=4))
    scale = np.abs(end) + 1
    assert np.all(np.abs(xs[:4, -1] - end) <= 1e-14 * scale)
    assert abs(xs[4, -1] - dt[0]) <= 1e-14 * (1 + dt[0])
    assert abs(q3[0] - q3_end[0]) <= 1e-14
    # Every interior sample is the closed form's state at its angle.
    arc = arc_frame(x0, AC, R, T)
    for k in range(1, 4):
        inner = np.array(arc_state(x0, arc, dtheta * k / 4), float).ravel()
        assert np.all(np.abs(xs[:4, k] - inner) <= 1e-14 * (np.abs(inner) + 1))


@pytest.mark.parametrize("x0, alpha_deg, dtheta", ONE_ARC_CASES)
def test_one_timed_segment_ends_where_the_clock_says(x0, alpha_deg, dtheta):
    """A duration equal to the closed form's own time over dtheta lands on dtheta."""
    alpha = math.radians(alpha_deg)
    R, T = (float(v) for v in radial_transverse(alpha))
    end, dt, _ = (np.array(v, float).ravel() for v in arc_end(x0, dtheta, AC, R, T, panels=4))
    xs, _ = propagate(x0, [alpha], [dt[0]], AC, samples=4, length_in="time", model=PLAIN)
    assert abs(xs[1, -1] - end[1]) < 1e-12
    assert np.all(np.abs(xs[:4, -1] - end) <= 1e-12 * (np.abs(end) + 1))


# -- against CVODES on the paper's scenario -------------------------------------------


@pytest.fixture(scope="module")
def paper_run():
    alphas = np.full(ARCS, ALPHA)
    xs, q3 = propagate(CIRCLE, alphas, six_month_arcs(), AC, samples=SAMPLES, length_in="time",
                       model=PLAIN)
    return xs, q3, cvodes_at_same_times(xs, alphas, SAMPLES)


def test_paper_scenario_radius_within_two_percent(paper_run):
    # Compared at the same time, as Fig. 5 plots it: the along-track lag of the
    # closed form then shows in r too, so this is the stricter reading of "over
    # 10 years" than Eq. 27's same-theta comparison (checked below as well).
    xs, q3, flown = paper_run
    assert np.all(q3 > 0)
    r0 = CIRCLE[0]
    worst = np.max(np.abs(xs[0] - flown[0])) / r0
    # Measured: 1.18 % (at 10 years).
    assert worst < 0.02
    # And not trivially small: 20 first-order arcs of half a revolution do err.
    assert worst > 1e-3


def test_paper_scenario_radius_at_same_theta(paper_run):
    xs, _, _ = paper_run
    flown = simulate(CIRCLE, np.full(ARCS * SAMPLES, ALPHA), np.diff(xs[1]), AC,
                     length_in="theta")
    # Eq. 27's measure (same theta). Measured: 1.22 %.
    assert np.max(np.abs(xs[0] - flown[0])) / CIRCLE[0] < 0.02


def test_newton_clock_residual_is_tiny(paper_run):
    xs, _, flown = paper_run
    asked = np.arange(ARCS + 1) * six_month_arcs()[0]
    # The rectification points sit at the asked times on the closed form's clock
    # (measured 1.4e-14 TU, i.e. 1e-9 s, after 10 years of 3.2 TU arcs).
    assert np.max(np.abs(xs[4, ::SAMPLES] - asked)) < 1e-12
    # ...and CVODES was flown to the same times.
    assert np.max(np.abs(flown[4] - xs[4])) < 1e-12
    # The same with one panel per arc, as the bench runs it (measured 1.4e-14 TU).
    ends, _ = propagate(CIRCLE, np.full(ARCS, ALPHA), six_month_arcs(), AC, length_in="time",
                        model=PLAIN)
    assert np.max(np.abs(ends[4] - asked)) < 1e-12


def test_attitude_switch_at_a_rectification_point():
    """+45 deg for five years, then -45 deg for five: raising, then lowering."""
    half = ARCS // 2
    plus, minus = np.full(ARCS, ALPHA), np.full(ARCS, -ALPHA)
    switch = np.r_[plus[:half], minus[half:]]

    def max_error(alphas, upto=None):
        xs, _ = propagate(CIRCLE, alphas, six_month_arcs(), AC, samples=SAMPLES,
                          length_in="time", model=PLAIN)
        flown = cvodes_at_same_times(xs, alphas, SAMPLES)
        return np.max(np.abs(xs[0] - flown[0])[:upto]), xs, flown

    err_switch, xs, flown = max_error(switch)
    # The bound: the arc lengths alone, with either attitude held over five years
    # (ten of the same six-month arcs), produce these errors; the switched run
    # carries the first half's error and adds the second half's, no more.
    upto = half * SAMPLES + 1
    err_plus_5y = max_error(plus, upto)[0]
    err_minus_5y = max_error(minus, upto)[0]
    bound = err_plus_5y + err_minus_5y
    # Measured: 0.0062 au against a bound of 0.0062 + 0.0081 = 0.0143 au.
    assert err_switch < bound
    # The switch is really flown: lowering brings r back near 1 au, while holding
    # +45 deg would have reached 1.64 au; the closed form follows CVODES there.
    assert abs(flown[0, -1] - 1.0) < 0.01
    assert abs(xs[0, -1] - flown[0, -1]) < bound


# -- the clock's root: Keplerian first guess, Newton residual, derivatives ------------

#: (x0, alpha_deg, dtheta): circular at 1 au, and an e = 0.53 orbit over 1.4 turns.
ECCENTRIC = (np.array([1.5, 0.0, 0.3, 0.6]), 45.0, 9.0)


def kepler_sweep_reference(x0, duration):
    """Angle swept on x0's Kepler orbit in ``duration`` (TU), from the classical
    anomalies and a bracketing root finder: independent of the propagator's form."""
    a, e, omega, _, nu0 = (float(v) for v in classical_from_polar(x0))
    n = a**-1.5

    def mean_anomaly(nu):
        # Continuous over revolutions: E - f is bounded, so unwrap through f.
        ecc = nu - 2 * math.atan2(e / (1 + math.sqrt(1 - e * e)) * math.sin(nu),
                                  1 + e / (1 + math.sqrt(1 - e * e)) * math.cos(nu))
        return ecc - e * math.sin(ecc)

    target = mean_anomaly(nu0) + n * duration
    return brentq(lambda d: mean_anomaly(nu0 + d) - target, 0.0, 8 * n * duration + 10,
                  xtol=1e-14)


@pytest.mark.parametrize("x0", [CIRCLE, ECCENTRIC[0], np.array([0.8, 1.0, -0.25, 1.2])])
@pytest.mark.parametrize("duration", [0.5, 3.2, 11.0])
def test_kepler_guess_is_the_keplerian_sweep(x0, duration):
    from esail_opt.physics.closed_form import arc_frame as frame

    x = ca.SX.sym("x", 4)
    d = ca.SX.sym("d")
    guess = ca.Function("guess", [x, d], [kepler_angle(frame(x, 0.0, 0.75, 0.25), d / x[0] ** 1.5)])
    assert float(guess(x0, duration)) == pytest.approx(
        kepler_sweep_reference(x0, duration), rel=1e-12, abs=1e-12)


def test_newton_converges_on_a_long_eccentric_arc():
    x0, alpha_deg, dtheta = ECCENTRIC
    alpha = math.radians(alpha_deg)
    R, T = (float(v) for v in radial_transverse(alpha))
    dt = float(arc_end(x0, dtheta, AC, R, T, panels=4)[1])
    xs, q3, residual = timed_arc_function(4, model=PLAIN)(np.r_[x0, 0.0], AC, alpha, dt)
    # Measured 1e-11 rad and 6e-12 TU (the starting-rate guess left 1e-3 rad).
    assert abs(float(np.array(xs)[1, -1]) - x0[1] - dtheta) < 1e-10
    assert abs(float(residual)) < 1e-10


def test_timed_arc_derivatives_finite_from_a_circle():
    # The guess is written without anomalies, which are undefined at e = 0: an
    # optimiser's first arc starts exactly there.
    x = ca.MX.sym("x", 5)
    d = ca.MX.sym("d")
    out = timed_arc_function(1, model=PLAIN)(x, AC, ALPHA, d)[0]
    z = ca.vertcat(x, d)
    jac = ca.Function("jacobian", [x, d], [ca.jacobian(out, z)])
    hess = ca.Function("hessian", [x, d], [ca.hessian(ca.sum1(out), z)[0]])
    point = (np.r_[CIRCLE, 0.0], six_month_arcs()[0])
    assert np.all(np.isfinite(np.array(jac(*point))))
    assert np.all(np.isfinite(np.array(hess(*point))))
    # The angle's derivative in the duration is the angular rate at the end, since
    # on the closed form dt/dtheta = r0^1.5 / (q3 s^2) = r / v_theta exactly.
    xs = np.array(timed_arc_function(1, model=PLAIN)(*point[:1], AC, ALPHA, point[1])[0])
    rate = xs[3, -1] / xs[0, -1]
    assert np.array(jac(*point))[1, 5] == pytest.approx(rate, rel=1e-10)


# -- convergence with the number of arcs, and Richardson extrapolation ---------------


@pytest.fixture(scope="module")
def truth_at_ten_years():
    return simulate(CIRCLE, [ALPHA], [time_from_years(YEARS)], AC)[:, -1]


def final_r_error(model, arcs, truth):
    xs, q3 = propagate(CIRCLE, [ALPHA] * arcs, six_month_arcs(arcs), AC, length_in="time",
                       model=model)
    assert np.all(q3 > 0)
    return abs(xs[0, -1] - truth[0])


def test_error_falls_like_one_over_arcs(truth_at_ten_years):
    # THEORY.md §5.2: 1/N.  Measured 1.025e-3 au at 320 arcs, 5.40e-4 au at 640.
    coarse = final_r_error(PLAIN, 320, truth_at_ten_years)
    fine = final_r_error(PLAIN, 640, truth_at_ten_years)
    assert 0.45 < fine / coarse < 0.6
    assert fine < 0.1 * final_r_error(PLAIN, ARCS, truth_at_ten_years)


def test_richardson_beats_plain_at_lower_cost(truth_at_ten_years):
    # 2 x_{2N} - x_N from 160 and 320 arcs costs 480 arcs; plain 640 costs more.
    # Measured 2.30e-4 au against 5.40e-4 au.
    extrapolated = final_r_error(RICHARDSON, 160, truth_at_ten_years)
    assert extrapolated < 0.5 * final_r_error(PLAIN, 640, truth_at_ten_years)
    # Second order: halving the arcs' length quarters the error (measured 0.242).
    finer = final_r_error(RICHARDSON, 320, truth_at_ten_years)
    assert 0.2 < finer / extrapolated < 0.3


def test_richardson_is_the_combination_of_whole_and_half_arcs():
    lengths = six_month_arcs(4)
    xs, _ = propagate(CIRCLE, [ALPHA, -ALPHA, 0.3, 0.0], lengths, AC,
                      throttles=[1.0, 0.5, 1.0, 0.0], length_in="time", model=RICHARDSON)
    whole, _ = propagate(CIRCLE, [ALPHA, -ALPHA, 0.3, 0.0], lengths, AC,
                         throttles=[1.0, 0.5, 1.0, 0.0], length_in="time", model=PLAIN)
    halves, _ = propagate(CIRCLE, np.repeat([ALPHA, -ALPHA, 0.3, 0.0], 2),
                          np.repeat(lengths / 2, 2), AC,
                          throttles=np.repeat([1.0, 0.5, 1.0, 0.0], 2), length_in="time",
                          model=PLAIN)
    assert np.allclose(xs, 2 * halves[:, ::2] - whole, rtol=1e-14, atol=1e-14)
