"""Many flights of one schedule on the closed form, in time, in compiled batches.

A Monte Carlo flies the same K pieces (each of constant pitch, clock and a_c) thousands
of times, each flight with its own a_c and angles per piece.  :class:`Ensemble` flies
them on :mod:`.batch`'s closed form over pieces given in time, compiled once for K
pieces.  A flight that starts part-way, at a guidance waypoint, ends with pieces of zero
length, which leave a state unchanged to the bit, so one compiled function serves every
waypoint.
"""

import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from esail_opt.propagation.arcs import ArcModel
from esail_opt.propagation.batch import batch3d_function, batch_function
from esail_opt.propagation.rectified3d import STATE, cartesian_states

#: Flights per call at most (1,000 flights of 80 arcs take about 0.25 s), so that a large
#: ensemble's calls share the cores.
CHUNK = 1000
#: The rows of a three-dimensional flight's Cartesian state.
CARTESIAN = slice(STATE, STATE + 6)
#: One arc a piece: the pieces are already the schedule's arcs.
PIECE = ArcModel(sub_arcs=1)


class Ensemble:
    """The flights of ``pieces`` pieces in three dimensions (``three_d``) or in the
    plane, ``chunk`` flights a compiled call, calls on ``threads`` threads at once
    (CasADi releases the interpreter's lock in compiled code; the states are the same on
    any number of threads).

    States are rows [r, theta, v_r, v_theta, t] (canonical), followed in three dimensions
    by the plane's unit quaternion [qw, qx, qy, qz] (``rectified3d``'s convention) and
    the Cartesian state [x, y, z, vx, vy, vz] in its fixed frame (rows
    :data:`CARTESIAN`).  A flight may start from a row with or without the Cartesian rows.
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
        """Every flight's state at its start and every piece's end, (M, width, K + 1), from
        ``starts`` (M, 9), (M, 15) or (M, 5); ``alphas`` and ``deltas`` (three dimensions
        only) (M, K) are the pitch and clock, rad, ``durations`` (K,) or (M, K) in TU (0
        leaves the state as it is), ``acs`` (M, K) canonical, throttle and factor included.
        """
        starts = self._with_cartesian(np.atleast_2d(np.asarray(starts, float)))
        m, k = starts.shape[0], self.pieces
        rows = [np.broadcast_to(np.asarray(v, float), (m, k))
                for v in (acs, alphas, *((deltas,) if self.three_d else ()), durations)]
        # In three dimensions a call maps one compiled flight, so there are at least as
        # many calls as threads; the planar batch is compiled across cases for one
        # width, so every call has that width, the last one padded.
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
