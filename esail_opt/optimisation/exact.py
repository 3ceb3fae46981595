"""Exact refinement: the closed-form optimum re-solved on Eqs. 1-2 with CVODES arcs.

The closed form is first-order, so its optimum misses the target by thousands of km once
flown on the full dynamics (THEORY.md §5.2).  The polish keeps the same piecewise-constant
problem -- the same segments, objective, target and path constraints, and the same
NLP builder (:func:`~esail_opt.optimisation.transcription.transcribe`) -- and swaps each
segment's closed-form arc for one CVODES integration of Eqs. 1-2 in time with
sensitivities (:func:`~esail_opt.optimisation.transcription.cvodes_time_segment`); the
segment durations become the length variables.  Only the closed form's q3 margin goes:
it has no meaning for an exact arc.

Every variable is warm-started from the closed-form optimum: the pitch as it is, the
durations from the NLP's segment times, and the nodes from a CVODES flight of that
schedule, so continuity holds at the start and Ipopt only has to remove the final miss.
"""

import dataclasses

from esail_opt.optimisation.problem import Tolerance
from esail_opt.optimisation.ipopt import ipopt_options, solve_transcription
from esail_opt.optimisation.transcription import cvodes_time_segment, transcribe
from esail_opt.propagation.simulate import SimulationError, simulate

#: Ipopt's bound on the final constraint violation (canonical units).  The verified miss
#: must be below 1 m against the polished NLP's own final node, and continuity defects
#: add up along the chain: at 1e-12 au (0.15 m per node) the 30-segment Earth-Mars coast
#: flew 1.67 m from its final node; at 1e-13 au, 0.02 m.
CONSTRAINT_TOLERANCE = 1e-13
#: What an exact schedule must meet: 1 m and 1 mm/s, against the target and against the
#: polished NLP's own final node.
TOLERANCE = Tolerance(position_km=1e-3, velocity_m_s=1e-3)


def polish_options(max_iter=200):
    """Ipopt options of the polish: the solve's, with a tighter constraint tolerance.

    The start is already near the optimum, so a small iteration budget suffices; a
    polish that needs more has a problem the user should see, not wait for.
    """
    opts = ipopt_options(max_iter=max_iter)
    opts["ipopt.constr_viol_tol"] = CONSTRAINT_TOLERANCE
    return opts


def warm_start(problem, result):
    """The polish NLP's starting point from a closed-form optimum.

    Parameters
    ----------
    problem : Problem
    result : NLPResult
        The closed-form optimum: its pitch, segment durations, departure, nodes and
        revolution class.

    Returns
    -------
    Guess
        Pitch, throttle and durations (TU) as the closed form's; nodes as
        :func:`exact_guess` flies them, or the closed form's own nodes if CVODES fails
        (an escaping flight, say), so a failed flight never blocks the polish.
    """
    return exact_guess(problem, result.x_start, result.as_guess(durations=True))


def exact_guess(problem, x_start, guess):
    """A start for the exact (CVODES-in-time) NLP from any schedule.

    ``guess`` holds the schedule (pitch, durations in TU, throttle) and its revolution
    class.  The nodes become the CVODES flight of that schedule from ``x_start``, so
    every continuity constraint holds at the start; if that flight fails, the guess's
    own nodes stay.  The polish passes a closed-form optimum here; the benchmark passes
    the constant-pitch seed (a cold start).
    """
    try:
        flown = simulate(x_start, guess.alpha, guess.lengths, problem.sail.ac,
                         throttles=guess.throttle, samples=1, length_in="time",
                         coefficients=problem.sail.coefficients)
    except SimulationError:
        return guess
    return dataclasses.replace(guess, nodes=flown[:, 1:])


def polish(problem, result, options=None):
    """Re-solve ``problem`` on exact CVODES arcs in time, warm-started from ``result``.

    Parameters
    ----------
    problem : Problem
    result : NLPResult
        The closed-form optimum (``ipopt.solve_problem``).  Its revolution class is
        kept: a window optimum's polish that lost its final-angle box would slide out of
        its window into another optimum.
    options : dict, optional
        Ipopt options; default :func:`polish_options`.

    Returns
    -------
    (NLPResult, Transcription)
        The exact optimum: ``durations`` are the polished segment times, ``lengths`` the
        angles they sweep, ``nodes`` the exact node states, ``q3`` empty;
        ``solve_seconds`` covers building the solver and Ipopt (not the warm-start flight).
    """
    tr = transcribe(problem, cvodes_time_segment(problem.sail.coefficients),
                    warm_start(problem, result), length_in="time")
    exact = solve_transcription(tr, polish_options() if options is None else options)
    return exact, tr
