"""The verifier3d bench's truth: heyoka in quadruple precision on the Cartesian equations
(``bench.verifier3d.truth``), against DOP853 on the Cartesian equations written out in
``test_plane_turn``."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from esail_opt.physics.elements import cartesian_from_polar3d
from esail_opt.physics.thrust import EXACT
from test_plane_turn import sail_acceleration
from test_rectified3d import AC, ALPHAS, DELTAS, PLANE, X0


def test_the_truth_is_the_cartesian_equations_flown_in_quadruple_precision():
    """Six segments of one time unit each, pitch and clock changing: heyoka's end is
    DOP853's at rtol 1e-13, to DOP853's own error."""
    from esail_opt.bench.verifier3d import has_quadruple, truth

    if not has_quadruple():
        pytest.skip("heyoka with quadruple precision (real128) is not installed")

    y0 = np.array(cartesian_from_polar3d(X0, PLANE)).ravel()
    durations = np.full(6, 1.0)
    exact = truth(y0, np.full(6, AC), ALPHAS, DELTAS, durations, EXACT)
    y = y0
    for alpha, delta, duration in zip(ALPHAS, DELTAS, durations):
        def rates(_, y, alpha=alpha, delta=delta):
            return np.r_[y[3:], -y[:3] / np.linalg.norm(y[:3]) ** 3
                         + sail_acceleration(y[:3], y[3:], AC, alpha, delta)]
        y = solve_ivp(rates, (0, duration), y, method="DOP853", rtol=1e-13,
                      atol=1e-15).y[:, -1]
    assert np.abs(exact - y).max() < 1e-11
