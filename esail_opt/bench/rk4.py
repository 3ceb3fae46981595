"""A fixed-step Runge-Kutta segment: the baseline a generic optimal-control tool gives.

Someone who writes this problem in a general CasADi optimal-control code, without the
closed form, would integrate Eqs. 1-2 with the classic fourth-order Runge-Kutta method
at a fixed number of steps per shooting segment.  :func:`rk4_segment` is that segment,
with the same signature as ``transcription.closed_form_segment``, so the same
multiple-shooting NLP can be solved with either and the two compared at equal verified
accuracy (``esail_opt.bench.precision``).
"""

import casadi as ca

from esail_opt.physics.dynamics import rhs_in_theta
from esail_opt.physics.thrust import EXACT, radial_transverse


def rk4_segment(steps, coefficients=EXACT):
    """One constant-pitch segment of Eqs. 1-2 in theta by ``steps`` classic RK4 steps.

    Theta is the independent variable, as in the closed-form NLP (the segment's length
    variable is its angle), and time is carried as the fifth state through dt/dtheta =
    r / v_theta (``dynamics.rhs_in_theta``), so the node times come out of the same
    integration.  The steps are equal: dtheta / ``steps`` each.

    Parameters
    ----------
    steps : int
        RK4 steps over the segment, >= 1.  The global error falls like steps^-4.
    coefficients : tuple of float
        (b1, b2) of Eqs. 3-4.

    Returns
    -------
    casadi.Function
        ``(x0[5], ac, alpha, dtheta) -> (x1[5], q3[0])``, SX and expanded:
        x = [r, theta, v_r, v_theta, t] canonical, ac the characteristic acceleration
        (times the throttle), alpha the pitch in rad, dtheta the segment's angle in rad.
        An integrator of the exact equations has no first-order validity margin, so q3
        is empty and ``transcription.transcribe`` adds no q3 rows for it.
    """
    if int(steps) != steps or steps < 1:
        raise ValueError(f"steps = {steps!r} is not a whole number >= 1")
    steps = int(steps)
    x = ca.SX.sym("x", 5)
    ac, alpha, h = ca.SX.sym("ac"), ca.SX.sym("alpha"), ca.SX.sym("h")
    R, T = radial_transverse(alpha, coefficients)

    def f(y):
        # The right-hand side does not depend on t (nor on theta), only on r, v_r, v_theta.
        return rhs_in_theta(y[:4], ac, R, T)

    k1 = f(x)
    k2 = f(x + h / 2 * k1)
    k3 = f(x + h / 2 * k2)
    k4 = f(x + h * k3)
    step = ca.Function("rk4_step", [x, ac, alpha, h],
                       [x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)])

    x0 = ca.SX.sym("x0", 5)
    ac, alpha, dtheta = ca.SX.sym("ac"), ca.SX.sym("alpha"), ca.SX.sym("dtheta")
    x1 = x0
    for _ in range(steps):
        x1 = step(x1, ac, alpha, dtheta / steps)
    # expand() inlines the step calls: one flat SX graph, which the NLP maps over its N
    # segments exactly as it maps the closed form's.
    return ca.Function("segment_rk4", [x0, ac, alpha, dtheta], [x1, ca.SX(0, 1)],
                       ["x0", "ac", "alpha", "dtheta"], ["x1", "q3"]).expand()
