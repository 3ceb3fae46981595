"""Guidance that still arrives: re-targeting a schedule in flight, on the closed form.

At each waypoint the spacecraft (its state known, the wind to come not) re-targets its
remaining pieces so that the closed form, flown at nominal thrust, meets the target's
position and velocity at the planned arrival; the remaining pitch, clock and asked a_c
each move by a quadratic in the fraction of the remaining time (nine coefficients,
:meth:`Retargeting.correct`).  The asked a_c stays within the sail's (the schedule's plus
any margin): at a minimum-a_c optimum without margin, guidance can only steer.
"""

from dataclasses import dataclass

import numpy as np

from esail_opt.propagation.ensemble import CARTESIAN

#: Gauss-Newton steps a waypoint, each on every flight's own prediction.
NEWTON_STEPS = 6
#: Times a flight still predicted to miss takes its own Jacobian afresh, a waypoint.
REFRESHES = 1
#: Step of the central differences of the Jacobian, rad.
STEP = 1e-5


def arrival(xs):
    """Cartesian [x, y, z, vx, vy, vz] (canonical) of the last state of each 3-D flight
    in ``xs`` (M, 15, K + 1), as an ensemble flies it."""
    return xs[:, CARTESIAN, -1]


@dataclass(frozen=True)
class Plan:
    """A schedule as pieces, canonical units: pitch and clock (rad), durations (TU) and
    the a_c each piece asks of the sail (throttle included) from ``start`` (a 3-D state
    row of :class:`~esail_opt.propagation.ensemble.Ensemble`), to meet ``target``
    (Cartesian, six components) at the end, within ``scale`` (the position and velocity
    tolerances, canonical), pitch within ``alpha_bounds`` (rad), the sail's full a_c
    ``sail_ac`` (the most a piece can ask)."""

    start: np.ndarray
    alphas: np.ndarray
    deltas: np.ndarray
    durations: np.ndarray
    acs: np.ndarray
    target: np.ndarray
    scale: tuple
    alpha_bounds: tuple
    sail_ac: float

    def weights(self):
        """Per-component weights of a Cartesian miss: one tolerance weighs 1."""
        return np.r_[np.full(3, 1 / self.scale[0]), np.full(3, 1 / self.scale[1])]


@dataclass
class Controls:
    """Each flight's pitch, clock (rad) and asked a_c (canonical) per piece, (M, K)."""

    alphas: np.ndarray
    deltas: np.ndarray
    acs: np.ndarray

    @classmethod
    def nominal(cls, plan, flights):
        return cls(*(np.tile(v, (flights, 1)) for v in (plan.alphas, plan.deltas, plan.acs)))

    def take(self, index):
        return Controls(self.alphas[index], self.deltas[index], self.acs[index])

    def repeat(self, times):
        """Each flight's controls ``times`` times over, in turn."""
        return Controls(*(np.repeat(v, times, axis=0) for v in (self.alphas, self.deltas,
                                                                 self.acs)))


def _rolled(values, first):
    """Each row's pieces from ``first`` on, moved to the front, zeros after."""
    out = np.zeros_like(values)
    out[:, : values.shape[1] - first] = values[:, first:]
    return out


def _basis(plan, first):
    """The correction's shape on the remaining pieces: (K - first, 3) columns 1, s, s^2
    of the fraction s of the remaining time at each piece's middle."""
    left = plan.durations[first:]
    mid = np.cumsum(left) - left / 2
    s = mid / max(left.sum(), 1e-300)
    return np.column_stack([np.ones_like(s), s, s * s])


#: Coefficients of a correction: three each for pitch, clock and the asked a_c.
COEFFICIENTS = 9
#: Singular values of the weighted Jacobian below this fraction of the largest are
#: left out of a correction: a direction the remaining flight can hardly move (at a
#: minimum-a_c optimum without margin, the a_c direction) is not pushed on.
RCOND = 1e-4


class Retargeting:
    """Guidance of ``plan`` flown on ``ensemble`` (three dimensions), re-targeting at
    the pieces ``waypoints`` (indices, each the first piece flown after re-targeting)."""

    def __init__(self, ensemble, plan, waypoints):
        self.ensemble = ensemble
        self.plan = plan
        # At piece 0 the flight is where the plan starts: nothing to correct.
        self.waypoints = sorted(set(int(w) for w in waypoints if 0 < w < len(plan.durations)))
        #: The predicted misses (tolerance units) after each waypoint's correction.
        self.predicted = []

    def _fly(self, states, controls, first, durations, factors=1.0):
        return self.ensemble.fly(states, _rolled(controls.alphas, first), durations,
                                 _rolled(controls.acs * factors, first),
                                 deltas=_rolled(controls.deltas, first))

    def _predict(self, states, controls, first):
        """Where each flight ends from ``states`` at piece ``first`` under ``controls``
        with the wind at its mean."""
        m = states.shape[0]
        left = _rolled(np.broadcast_to(self.plan.durations, (m, self.plan.durations.size)),
                       first)
        return arrival(self._fly(states, controls, first, left))

    def _apply(self, controls, first, coefficients):
        """``controls`` with the correction ``coefficients`` (M, 9) on pieces ``first``
        on, pitch within its bounds and the asked a_c within [0, the sail's]."""
        basis = _basis(self.plan, first).T
        out = Controls(controls.alphas.copy(), controls.deltas.copy(), controls.acs.copy())
        out.alphas[:, first:] += coefficients[:, 0:3] @ basis
        out.deltas[:, first:] += coefficients[:, 3:6] @ basis
        out.acs[:, first:] *= 1 + coefficients[:, 6:9] @ basis
        np.clip(out.alphas, *self.plan.alpha_bounds, out=out.alphas)
        np.clip(out.acs, 0.0, self.plan.sail_ac, out=out.acs)
        return out

    def _miss(self, states, controls, first, coefficients):
        tried = self._apply(controls, first, coefficients)
        return (self._predict(states, tried, first) - self.plan.target) * self.plan.weights()

    def _jacobians(self, states, controls, first, coefficients):
        """d(weighted arrival)/d(coefficients) (M x 6 x 9) of each flight from its state
        at piece ``first`` under its controls and ``coefficients``, by central
        differences (the probes of all flights in one ensemble call)."""
        probes = np.vstack([STEP * np.eye(COEFFICIENTS), -STEP * np.eye(COEFFICIENTS)])
        n = len(probes)
        trial = (coefficients[:, None, :] + probes).reshape(-1, COEFFICIENTS)
        ends = self._miss(np.repeat(states, n, axis=0), controls.repeat(n), first, trial)
        ends = ends.reshape(len(states), n, -1)
        return ((ends[:, :COEFFICIENTS] - ends[:, COEFFICIENTS:]) / (2 * STEP)).transpose(0, 2, 1)

    def _newton(self, states, controls, first, jac, coefficients, miss):
        """Gauss-Newton steps from ``coefficients`` and their ``miss``, each flight's ``jac``
        Broyden-updated by its own steps; a step is kept only where it lowers that
        flight's miss, else shortened.  Returns (coefficients, miss)."""
        coefficients, miss, jac = coefficients.copy(), miss.copy(), jac.copy()
        size = np.linalg.norm(miss, axis=1)
        scale = np.ones(len(states))
        for _ in range(NEWTON_STEPS):
            step = -np.einsum("mij,mj->mi", np.linalg.pinv(jac, rcond=RCOND), miss)
            trial = coefficients + scale[:, None] * step
            trial_miss = self._miss(states, controls, first, trial)
            moved, change = trial - coefficients, trial_miss - miss
            # The secant of this step, taken or not, corrects the flight's Jacobian.
            predicted = np.einsum("mij,mj->mi", jac, moved)
            norm = np.maximum(np.einsum("mi,mi->m", moved, moved), 1e-300)
            jac += np.einsum("mi,mj->mij", change - predicted, moved) / norm[:, None, None]
            trial_size = np.linalg.norm(trial_miss, axis=1)
            better = trial_size < size
            coefficients[better], miss[better], size[better] = (
                trial[better], trial_miss[better], trial_size[better])
            scale = np.where(better, np.minimum(2 * scale, 1.0), scale / 4)
        return coefficients, miss

    def correct(self, states, controls, first, nominal_state):
        """``controls`` re-targeted from ``states`` at piece ``first``.

        Gauss-Newton steps on the miss weighted by the tolerances (:meth:`_newton`), from
        the nominal's Jacobian; a flight still predicted to miss by more than its
        tolerance takes its own Jacobian and steps again, since far from the nominal the
        nominal's can point the wrong way.  A miss too large to remove is left as small
        as the steps made it.
        """
        m = states.shape[0]
        zero = np.zeros((1, COEFFICIENTS))
        nominal = self._jacobians(nominal_state[None], Controls.nominal(self.plan, 1), first,
                                  zero)
        coefficients = np.zeros((m, COEFFICIENTS))
        miss = self._miss(states, controls, first, coefficients)
        coefficients, miss = self._newton(states, controls, first,
                                          np.repeat(nominal, m, axis=0), coefficients, miss)
        for _ in range(REFRESHES):
            far = np.flatnonzero(np.linalg.norm(miss, axis=1) > 1.0)
            if not far.size:
                break
            own = controls.take(far)
            jac = self._jacobians(states[far], own, first, coefficients[far])
            coefficients[far], miss[far] = self._newton(states[far], own, first, jac,
                                                        coefficients[far], miss[far])
        self.predicted.append(np.linalg.norm(miss, axis=1))
        return self._apply(controls, first, coefficients)

    def fly(self, factors, nominal):
        """The flights of the wind ``factors`` (M, K) with re-targeting at every
        waypoint; ``nominal`` is the nominal flight's states (width, K + 1), whose
        Jacobians the corrections use.  Returns the states (M, width, K + 1) and the
        :class:`Controls` flown."""
        p = self.plan
        m, k = factors.shape
        controls = Controls.nominal(p, m)
        states = np.tile(p.start, (m, 1))
        out = np.empty((m, self.ensemble.width, k + 1))
        first = 0
        for stop in self.waypoints + [k]:
            # Pieces first .. stop - 1 under the wind; the rest of the call is zeros.
            span = np.zeros((m, k))
            span[:, : stop - first] = p.durations[first:stop]
            xs = self._fly(states, controls, first, span, factors)
            out[:, :, first: stop + 1] = xs[:, :, : stop - first + 1]
            states = out[:, :, stop]
            first = stop
            if first < k:
                controls = self.correct(states, controls, first, nominal[:, first])
        return out, controls
