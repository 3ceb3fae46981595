"""The 3-D rectified closed form (``propagation.rectified3d``, ``batch.propagate_batch3d``)
against the Cartesian flights: CVODES on the Cartesian equations (``simulate.simulate3d``),
itself checked here against DOP853 on the Cartesian equations written out in
``test_plane_turn``, and RK4 on them (``rk4.rk4_segment3d``)."""

import math

import numpy as np
import pytest

from esail_opt.physics import rotation
from esail_opt.physics.constants import accel_from_mm_s2
from esail_opt.physics.elements import cartesian_from_polar3d, polar_from_classical
from esail_opt.propagation.arcs import FIRST_ORDER, ArcModel
from esail_opt.propagation.batch import propagate_batch3d
from esail_opt.propagation.rectified import propagate
from esail_opt.propagation.rectified3d import propagate3d
from esail_opt.propagation.rk4 import rk4_segment3d
from esail_opt.propagation.simulate import VERIFY_TOLERANCE, simulate, simulate3d
from test_plane_turn import fly_cartesian_theta

AC = accel_from_mm_s2(1.0)
X0 = np.array(polar_from_classical(1.0, 0.1, 0.5, 1.0)).ravel()
PLANE = np.array(rotation.from_rotation_vector([0.03, -0.05, 0.4])).ravel()
#: Six segments of one radian at 1 mm/s^2, clocks on both sides of the plane.
ALPHAS = np.radians([40, 35, 50, -20, 45, 30])
DELTAS = np.radians([30, -60, 90, 120, -30, 10])
LENGTHS = np.full(6, 1.0)


def cartesian(xs, column=-1):
    return np.array(cartesian_from_polar3d(xs[:4, column], xs[5:, column])).ravel()


def reference():
    """The schedule flown by Cartesian CVODES (lengths: angles the Sun-sail line sweeps)."""
    y0 = np.array(cartesian_from_polar3d(X0, PLANE)).ravel()
    return simulate3d(y0, ALPHAS, DELTAS, LENGTHS, AC, length_in="theta",
                      tol=VERIFY_TOLERANCE)


def test_cvodes_3d_is_dop853_on_the_cartesian_equations():
    """simulate3d in theta ends where DOP853 on the Cartesian equations (written out in
    the tests with Huo's geometry) does, segment after segment."""
    ref = reference()
    y = ref[:6, 0]
    for k, (alpha, delta, length) in enumerate(zip(ALPHAS, DELTAS, LENGTHS)):
        y = fly_cartesian_theta(y, AC, alpha, delta, length)
        assert np.abs(y - ref[:6, k + 1]).max() < 1e-10


def test_cvodes_3d_in_time_in_the_plane_is_eqs_1_2():
    """In the fixed x-y plane at delta = 0, the Cartesian flight in time is the polar
    flight of Eqs. 1-2 (``simulate.simulate``)."""
    x0 = np.array([1.0, 0.2, 0.05, 0.98])
    durations = [2.0, 3.0, 1.5]
    polar = simulate(x0, ALPHAS[:3], durations, AC, tol=VERIFY_TOLERANCE)
    y0 = np.array(cartesian_from_polar3d(x0, rotation.IDENTITY)).ravel()
    cart = simulate3d(y0, ALPHAS[:3], np.zeros(3), durations, AC, tol=VERIFY_TOLERANCE)
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


def test_batch_3d_is_the_single_case():
    starts = np.array([X0, [1.2, 0.0, 0.0, 0.9]])
    planes = np.array([PLANE, rotation.IDENTITY])
    alphas = np.array([ALPHAS[:3], ALPHAS[3:]])
    deltas = np.array([DELTAS[:3], DELTAS[3:]])
    lengths = np.array([[1.0, 2.0, 0.5], [0.3, 0.4, 2.0]])
    acs = [AC, 0.5 * AC]
    xs, q3 = propagate_batch3d(starts, planes, alphas, deltas, lengths, acs, samples=2)
    for m in range(2):
        one, one_q3 = propagate3d(starts[m], planes[m], alphas[m], deltas[m], lengths[m],
                                  acs[m], samples=2)
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
