"""Consistency of the stored collocation reference optima (tests/reference/).

``tests/reference/collocation_min_time.json`` holds minimum-time circle-to-circle transfers
solved by ``esail_opt.bench.collocation`` (continuous-pitch Radau collocation of Eqs. 1-2).
Other tests compare the project's optimiser against them, so here we check, without
re-solving anything, that the stored numbers hang together:

* the mesh refinement study converged (halving the step moved tof by < 0.01 %);
* the reported optimum is the best of the local optima found and respects the exact
  lower bound tof >= |sqrt(R) - 1| / (a_c / 4) (Eq. 2: d(r v_theta)/dt = a_c T, |T| <= 1/4);
* the stored control profile (pitch on the fine collocation grid, piecewise-cubic in
  time) is continuous and, integrated independently here (numpy right-hand side written
  below, not the package's casadi one), reproduces the angular momentum gain exactly and
  flies to the target orbit.  The whole module runs in about a second.
"""

import json
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from conftest import REPO

REFERENCE = REPO / "tests" / "reference" / "collocation_min_time.json"
CASES = ("earth_mars", "earth_venus", "earth_mars_low", "earth_venus_low")

# Unit facts restated here so the checks do not lean on the package's conversions.
MU_SUN = 1.32712440018e20  # m^3/s^2
AU = 1.495978707e11  # m
TU_DAYS = math.sqrt(AU**3 / MU_SUN) / 86400.0
ACC_UNIT_MM_S2 = MU_SUN / AU**2 * 1e3
VU_M_S = AU / (TU_DAYS * 86400.0)

# Bounds on the final-state miss of the DOP853 (1e-12) re-integration stored in the JSON:
# the collocation on the fine mesh flies to the target within metres to a few km.
MISS_R_KM = 1.0
MISS_V_M_S = 1e-3


@pytest.fixture(scope="module")
def reference():
    return json.loads(REFERENCE.read_text())


@pytest.fixture(params=CASES)
def case(request, reference):
    return reference[request.param]


def _canonical_ac(case):
    return case["ac_mm_s2"] / ACC_UNIT_MM_S2


def _control(case):
    """Piecewise-cubic alpha(t) (radians, canonical time) as the JSON describes it:
    per-interval power-basis coefficients in the local variable s = t/h - k in [0, 1]."""
    nodes = np.asarray(case["control"]["nodes"])
    alpha = np.radians(case["control"]["alpha_deg"])
    n = case["intervals_fine"]
    tf = case["tof_days"] / TU_DAYS
    assert alpha.size == 3 * n + 1
    # Power-basis coefficients of each interval's interpolating cubic (highest first).
    vander_inv = np.linalg.inv(np.vander(nodes, 4))
    coeffs = np.array([vander_inv @ alpha[3 * k:3 * k + 4] for k in range(n)])
    return coeffs, tf / n, n


def test_json_has_every_case_and_says_how_it_was_made(reference):
    assert set(CASES) <= set(reference)
    # The file records the command that wrote it: the solver ran as the script
    # tests/reference/collocation.py before it became the module esail_opt.bench.collocation.
    assert any(name in reference["how"] for name in
               ("esail_opt.bench.collocation", "tests/reference/collocation.py"))


def test_mesh_refinement_converged(case):
    rel = abs(case["tof_days_fine"] - case["tof_days_coarse"]) / case["tof_days_fine"]
    assert rel == pytest.approx(case["relative_change"], rel=1e-6, abs=1e-15)
    assert case["relative_change"] < 1e-4
    assert case["intervals_fine"] == 2 * case["intervals"]
    assert case["tof_days"] == case["tof_days_fine"]


def test_optimum_is_best_local_optimum_and_above_lower_bound(case):
    optima = case["local_optima"]
    assert optima
    assert case["tof_days"] <= min(o["tof_days"] for o in optima) * (1 + 1e-6)
    assert any(abs(o["revolutions"] - case["revolutions"]) < 1e-3 for o in optima)
    assert case["revolutions"] == pytest.approx(case["theta_f_rad"] / (2 * math.pi))
    dh = abs(math.sqrt(case["rf_au"]) - math.sqrt(case["r0_au"]))
    lower_bound_days = dh / (_canonical_ac(case) / 4) * TU_DAYS
    assert case["tof_lower_bound_days"] == pytest.approx(lower_bound_days, rel=1e-9)
    assert case["tof_days"] > lower_bound_days


def test_stored_verification_miss_is_small(case):
    ver = case["verification"]
    assert ver["rtol"] <= 1e-12 and ver["atol"] <= 1e-12
    assert ver["miss_r_km"] < MISS_R_KM
    assert ver["miss_v_m_s"] < MISS_V_M_S
    # The pitch maximises lam_v . (R, T) at every collocation point (Pontryagin's minimum
    # principle read off Ipopt's multipliers): the cosine is 1 everywhere.
    assert ver["minimum_principle_cosine_min_max"][0] > 1 - 1e-6
    for o in case["local_optima"]:  # every reported optimum was a flying, PMP-consistent one
        assert o["verification"]["miss_r_km"] < 100.0 and o["verification"]["miss_v_m_s"] < 0.1
        assert o["verification"]["minimum_principle_cosine_min_max"][0] > 1 - 1e-6


def test_stored_control_is_continuous(case):
    """Neighbouring grid values differ by a few degrees at most: no chattering, no
    unresolved 180-degree wraps."""
    alpha = np.asarray(case["control"]["alpha_deg"])
    assert np.max(np.abs(np.diff(alpha))) < 10.0


def test_angular_momentum_gain_matches_stored_control(case):
    """Eq. 2 makes h = r v_theta grow as dh/dt = a_c T(alpha(t)) whatever the state, so
    the stored control alone must give h_f - h_0 = sqrt(R) - 1.  8-point Gauss-Legendre
    on each interval integrates T of the cubic pitch exactly enough; what is left is the
    collocation's own error."""
    coeffs, h, n = _control(case)
    x, w = np.polynomial.legendre.leggauss(8)
    s = 0.5 * (x + 1.0)
    alpha = np.array([np.polyval(c, s) for c in coeffs])  # n x 8
    integral_T = np.sum(0.25 * np.sin(2 * alpha) @ (0.5 * w)) * h
    dh = math.sqrt(case["rf_au"]) - math.sqrt(case["r0_au"])
    assert _canonical_ac(case) * integral_T == pytest.approx(dh, rel=1e-7, abs=1e-9)


def _eqs_1_2(t, y, ac, alpha_of_t):
    """Eqs. 1-2 with the E-sail acceleration a_c (1 au / r) (R, T), exact b1, b2."""
    r, _, vr, vt = y
    alpha = alpha_of_t(t)
    R = 0.75 + 0.25 * math.cos(2 * alpha)
    T = 0.25 * math.sin(2 * alpha)
    return [vr, vt / r, vt * vt / r - 1.0 / (r * r) + ac * R / r, -vr * vt / r + ac * T / r]


def test_stored_control_flies_to_target_orbit(case):
    """Re-integrate the stored control with a hand-written right-hand side (DOP853 takes
    about one step per interval, so even the 1100-interval spirals take a fraction of a
    second)."""
    coeffs, h, n = _control(case)
    ac = _canonical_ac(case)
    y = np.array([case["r0_au"], 0.0, 0.0, 1.0])
    for k in range(n):  # interval by interval: the control is only C0 at the joints
        def alpha_k(t, c=coeffs[k], k=k):
            return np.polyval(c, t / h - k)
        sol = solve_ivp(_eqs_1_2, (k * h, (k + 1) * h), y, method="DOP853",
                        rtol=1e-11, atol=1e-11, args=(ac, alpha_k))
        y = sol.y[:, -1]
    rf = case["rf_au"]
    assert abs(y[0] - rf) * AU / 1e3 < MISS_R_KM
    assert math.hypot(y[2], y[3] - 1 / math.sqrt(rf)) * VU_M_S < MISS_V_M_S
    assert y[1] / (2 * math.pi) == pytest.approx(case["revolutions"], abs=1e-6)
