"""Many flights of one schedule on the closed form, in time, in compiled batches.

A Monte Carlo of a schedule flies the same K pieces (each of constant pitch, clock and
a_c) thousands of times, each flight with its own a_c per piece and, under guidance,
its own angles from some piece on.  :class:`Ensemble` is that: the batched closed form
of :mod:`.batch` over pieces given in time (the attitude changes on the spacecraft's
clock, as a flown schedule does), compiled once for K pieces and a fixed number of
flights a call, with larger ensembles cut into calls of that size.  A flight that
starts part-way, at a guidance waypoint, flies its remaining pieces first and then
pieces of zero length, which leave a state unchanged to the bit, so one compiled
function serves every waypoint.
"""

import numpy as np

from esail_opt.propagation.arcs import ArcModel
from esail_opt.propagation.batch import batch3d_function, batch_function

#: Flights per compiled call, however many are flown: one compile (about 0.5 s)
#: serves the nominal, the guidance's probes and every ensemble, a smaller call being
#: padded (a call of 1,000 flights of an 80-arc schedule costs about 0.25 s).
CHUNK = 1000
#: One arc a piece: the pieces are already the schedule's arcs.
PIECE = ArcModel(sub_arcs=1)


class Ensemble:
    """The flights of ``pieces`` pieces in three dimensions (``three_d``) or in the
    plane, ``chunk`` flights a compiled call.

    States are rows [r, theta, v_r, v_theta, t] (canonical units, the in-plane polar
    state and the time), followed in three dimensions by the plane's unit quaternion
    [qw, qx, qy, qz] (``rectified3d``'s convention).
    """

    def __init__(self, pieces, three_d, chunk=CHUNK):
        self.pieces = pieces
        self.three_d = three_d
        self.chunk = chunk
        self.width = 9 if three_d else 5

    def _function(self, cases):
        if self.three_d:
            return batch3d_function(self.pieces, cases, length_in="time", model=PIECE,
                                    jit=True)
        return batch_function(self.pieces, cases, length_in="time", model=PIECE, jit=True)

    def fly(self, starts, alphas, durations, acs, deltas=None):
        """Every flight from its start through its pieces.

        Parameters
        ----------
        starts : array_like, shape (M, 9) or (M, 5)
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
        starts = np.atleast_2d(np.asarray(starts, float))
        m, k = starts.shape[0], self.pieces
        rows = [np.broadcast_to(np.asarray(v, float), (m, k))
                for v in (acs, alphas, *((deltas,) if self.three_d else ()), durations)]
        cases = self.chunk
        fun = self._function(cases)
        out = np.empty((m, self.width, k + 1))
        for first in range(0, m, cases):
            take = np.arange(first, first + cases).clip(max=m - 1)  # the last call padded
            xs, _ = fun(starts[take].T, *(row[take].reshape(1, -1) for row in rows))
            xs = np.array(xs).reshape(self.width, cases, k).transpose(1, 0, 2)
            n = min(cases, m - first)
            out[first:first + n, :, 0] = starts[first:first + n]
            out[first:first + n, :, 1:] = xs[:n]
        return out
