"""Many flights of one schedule on the closed form, in time, in compiled batches.

A Monte Carlo of a schedule flies the same K pieces (each of constant pitch, clock and
a_c) thousands of times, each flight with its own a_c per piece and, under guidance,
its own angles from some piece on.  :class:`Ensemble` is that: the batched closed form
of :mod:`.batch` over pieces given in time (the attitude changes on the spacecraft's
clock, as a flown schedule does), compiled once for K pieces, with larger ensembles
cut into calls of at most ``chunk`` flights.  A flight that starts part-way, at a
guidance waypoint, flies its remaining pieces first and then pieces of zero length,
which leave a state unchanged to the bit, so one compiled function serves every
waypoint.
"""

import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from esail_opt.propagation.arcs import ArcModel
from esail_opt.propagation.batch import batch3d_function, batch_function
from esail_opt.propagation.rectified3d import STATE, cartesian_states

#: Flights per call at most (a call of 1,000 flights of an 80-arc schedule costs about
#: 0.25 s), so that a large ensemble's calls share the cores.
CHUNK = 1000
#: The rows of a three-dimensional flight's Cartesian state.
CARTESIAN = slice(STATE, STATE + 6)
#: One arc a piece: the pieces are already the schedule's arcs.
PIECE = ArcModel(sub_arcs=1)


class Ensemble:
    """The flights of ``pieces`` pieces in three dimensions (``three_d``) or in the
    plane, ``chunk`` flights a compiled call, calls on ``threads`` threads at once
    (CasADi releases the interpreter's lock while compiled code runs; each call writes
    its own flights, so the states are the same on any number of threads).

    States are rows [r, theta, v_r, v_theta, t] (canonical units, the in-plane polar
    state and the time), followed in three dimensions by the plane's unit quaternion
    [qw, qx, qy, qz] (``rectified3d``'s convention) and the Cartesian state [x, y, z,
    vx, vy, vz] in the quaternions' fixed frame (rows :data:`CARTESIAN`), converted in
    the same compiled call.  A flight may start from a row of either width.
    """

    def __init__(self, pieces, three_d, chunk=CHUNK, threads=os.cpu_count() or 1):
        self.pieces = pieces
        self.three_d = three_d
        self.chunk = chunk
        self.threads = threads
        self.polar = STATE if three_d else 5
        self.width = self.polar + (6 if three_d else 0)

    def _function(self, cases):
        if self.three_d:
            return batch3d_function(self.pieces, cases, length_in="time", model=PIECE,
                                    jit=True, cartesian=True)
        return batch_function(self.pieces, cases, length_in="time", model=PIECE, jit=True)

    def _with_cartesian(self, starts):
        if not self.three_d or starts.shape[1] == self.width:
            return starts
        return np.column_stack([starts, cartesian_states(starts.T)[:6].T])

    def fly(self, starts, alphas, durations, acs, deltas=None):
        """Every flight from its start through its pieces.

        Parameters
        ----------
        starts : array_like, shape (M, 9), (M, 15) or (M, 5)
            Start states (see the class).
        alphas, deltas : array_like, shape (M, K)
            Pitch and clock of each piece, rad (``deltas`` only in three dimensions).
        durations : array_like, shape (K,) or (M, K)
            Each piece's duration, TU (0 leaves the state as it is).
        acs : array_like, shape (M, K)
            Each piece's characteristic acceleration, canonical (throttle and factor
            included).

        Returns
        -------
        numpy.ndarray, shape (M, width, K + 1)
            Each flight's state at its start and at every piece's end.
        """
        starts = self._with_cartesian(np.atleast_2d(np.asarray(starts, float)))
        m, k = starts.shape[0], self.pieces
        rows = [np.broadcast_to(np.asarray(v, float), (m, k))
                for v in (acs, alphas, *((deltas,) if self.three_d else ()), durations)]
        # In three dimensions a call maps one compiled flight, so the flights are cut
        # into as many calls as there are threads, or more; the planar batch is
        # compiled across cases for one width, so its calls all have that width, the
        # last one padded.
        cases = (min(self.chunk, -(-m // self.threads)) if self.three_d else self.chunk)
        fun = self._function(cases)
        out = np.empty((m, self.width, k + 1))
        out[:, :, 0] = starts

        def call(first):
            take = np.arange(first, first + cases).clip(max=m - 1)
            xs, _, *cartesian = fun(starts[take, :self.polar].T,
                                    *(row[take].reshape(1, -1) for row in rows))
            n = min(cases, m - first)
            out[first:first + n, :self.polar, 1:] = _by_flight(xs, cases, k)[:n]
            if cartesian:
                out[first:first + n, CARTESIAN, 1:] = _by_flight(cartesian[0], cases, k)[:n, :6]

        calls = range(0, m, cases)
        if len(calls) == 1 or self.threads == 1:
            for first in calls:
                call(first)
        else:
            with ThreadPoolExecutor(min(self.threads, len(calls))) as pool:
                list(pool.map(call, calls))
        return out


def _by_flight(columns, cases, k):
    """A call's output columns (rows x cases K) as (cases, rows, K)."""
    columns = np.array(columns)
    return columns.reshape(columns.shape[0], cases, k).transpose(1, 0, 2)
