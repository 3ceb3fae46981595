"""Many fixed-attitude cases propagated by the closed form in one mapped call.

A survey (which pitch and a_c reach where, and when) and the paper's Figs. 3-4 are
grids of propagations that differ only in their numbers.  Each is one case of the
same ``casadi.Function``, so the grid is that Function's ``map`` over M cases: one
call from Python, one loop in CasADi, no Python loop over cases.  The single-case
Functions of :mod:`.rectified` are mapped as they are, so a case of the batch is the
single-case propagator's answer to rounding (tests check it case by case).

Two shapes are batched:

* a rectified schedule of N segments (:func:`batch_function`, numbers through
  :func:`propagate_batch`): ``rectified.rectified_function`` mapped;
* the paper's single first-order arc at angles given per case
  (:func:`angles_batch_function`, numbers through :func:`arcs_at_angles`), so that arcs
  of different sample counts (Fig. 4 has hundreds) share one call.

``jit`` compiles the mapped Function to C with CasADi's own just-in-time compiler,
for this process only.  Why not ``propagation.compiled``'s disk cache: it compiles a
Function together with its Jacobian and Hessian blocks, which the NLP needs; a timed
second-order arc (its clock guess and Taylor series inside) has a Hessian far too large
to compile for a call that is never differentiated, while its forward evaluation alone
compiles in seconds.  Without a compiler, or with ``ESAIL_OPT_COMPILE=0``, the
Function stays on CasADi's virtual machine.
"""

import functools
import logging
import os
import tempfile

import casadi as ca
import numpy as np

from esail_opt.physics.thrust import EXACT
from esail_opt.propagation import compiled
from esail_opt.propagation.arcs import PANEL_NODES, ArcModel
from esail_opt.propagation.rectified import angles_function, rectified_function
from esail_opt.propagation.rectified3d import STATE, rectified3d_function

log = logging.getLogger("esail_opt")

#: Flags of the just-in-time compile.  On the bench's batch -O2 and -O3 ran within the
#: timing noise of -O1 and compiled slower; -march=native, a little faster, is left out
#: because a compiler that refuses it would leave the batch on the virtual machine.
JIT_FLAGS = ("-O1",)
#: Where the compile's source and library live while the batch is loaded: the system's
#: temporary folder, not the working directory (which may be read-only, or the user's).
_JIT_FOLDER = tempfile.gettempdir() + os.sep


def _native(fun):
    """``fun`` compiled to C in this process, or ``fun`` itself on the virtual machine
    (compiling off, or the compile failed: one warning)."""
    if not compiled.enabled():
        return fun
    symbols = [ca.MX.sym(fun.name_in(k), fun.sparsity_in(k)) for k in range(fun.n_in())]
    try:
        return ca.Function(f"{fun.name()}_jit", symbols, fun(*symbols), fun.name_in(),
                           fun.name_out(), {"jit": True, "compiler": "shell",
                                            "jit_options": {"flags": list(JIT_FLAGS),
                                                            "verbose": False,
                                                            "directory": _JIT_FOLDER}})
    except RuntimeError as err:
        log.warning("esail-opt: compiling the batch %s failed (%s); it stays on CasADi's "
                    "virtual machine", fun.name(), str(err).strip().splitlines()[-1])
        return fun


@functools.lru_cache(maxsize=None)
def batch_function(segments, cases, *, samples=1, length_in="theta", coefficients=EXACT,
                   model=ArcModel(), jit=False):
    """``rectified.rectified_function`` (same arguments) mapped over ``cases``.

    ``(x0[5 x M], ac[1 x M N], alpha[1 x M N], length[1 x M N]) ->
    (xs[5 x M N S samples], q3[1 x M N S])``, S = ``model.sub_arcs``: case m's columns
    are the m-th block of each (its N S arcs, its N S samples-per-arc states).  With
    ``jit`` the whole map is compiled to C in this process (see the module's docstring);
    that is apart from ``model.native``, which flies the arcs on the disk cache's
    compiled panels.
    """
    single = rectified_function(segments, samples=samples, length_in=length_in,
                                coefficients=coefficients, model=model)
    mapped = single.map(cases)
    return _native(mapped) if jit else mapped


def _rows(values, cases, width, name):
    """``values`` as a float array of shape (cases, width): a scalar or a (width,) row is
    repeated for every case."""
    values = np.asarray(values, float)
    if values.ndim == 2 and values.shape[0] == 1:
        values = values[0]
    if values.ndim <= 1 and values.size in (1, width):
        return np.broadcast_to(values.reshape(1, -1), (cases, width)).astype(float)
    if values.shape != (cases, width):
        raise ValueError(f"{name} has shape {values.shape}, expected ({cases}, {width})")
    return values


def propagate_batch(x0, alphas, lengths, ac, *, throttles=None, samples=1, length_in="theta",
                    coefficients=EXACT, model=ArcModel(), jit=False):
    """:func:`rectified.propagate` for M cases in one call.

    Parameters
    ----------
    x0 : array_like, shape (4,) or (M, 4)
        Polar start states [r, theta, v_r, v_theta], canonical units; one for all cases,
        or one per case.
    alphas, lengths : array_like, shape (M, N)
        Pitch (rad) and length (angle or duration, as ``length_in``) of each case's
        segments; a (N,) row serves every case.
    ac : float or array_like, shape (M,)
        Characteristic acceleration per case, canonical units.
    throttles : array_like, shape (M, N) or (N,), optional
        Factor on ac per segment, default 1.
    samples, length_in, coefficients, model
        As :func:`rectified.propagate`.
    jit : bool
        Compile the mapped Function to C (see the module's docstring).

    Returns
    -------
    xs : numpy.ndarray, shape (M, 5, N * S * samples + 1)
        Each case's [r, theta, v_r, v_theta, t] at its start and at every sample
        (S = ``model.sub_arcs``).
    q3 : numpy.ndarray, shape (M, N * S)
        Validity margins at each arc's end.
    """
    starts = np.atleast_2d(np.asarray(x0, float))
    n = np.shape(np.atleast_2d(alphas))[1]
    cases = max(starts.shape[0], np.shape(np.atleast_2d(alphas))[0],
                np.shape(np.atleast_2d(lengths))[0], np.size(ac))
    alphas = _rows(alphas, cases, n, "alphas")
    lengths = _rows(lengths, cases, n, "lengths")
    kappa = _rows(1.0 if throttles is None else throttles, cases, n, "throttles")
    acs = np.broadcast_to(np.asarray(ac, float).reshape(-1, 1), (cases, 1))
    starts = np.column_stack([_rows(starts, cases, 4, "x0"), np.zeros(cases)])
    fun = batch_function(n, cases, samples=samples, length_in=length_in,
                         coefficients=coefficients, model=model, jit=jit)
    xs, q3 = fun(starts.T, (acs * kappa).reshape(1, -1), alphas.reshape(1, -1),
                 lengths.reshape(1, -1))
    arcs = n * model.sub_arcs
    xs = np.array(xs).reshape(5, cases, arcs * samples).transpose(1, 0, 2)
    return (np.concatenate([starts[:, :, None], xs], axis=2),
            np.array(q3).reshape(cases, arcs))


@functools.lru_cache(maxsize=None)
def angles_batch_function(samples, cases, *, coefficients=EXACT, nodes=PANEL_NODES, jit=False):
    """``rectified.angles_function`` mapped over ``cases``: ``(x0[5 x M], ac[1 x M],
    alpha[1 x M], phis[1 x M (samples + 1)]) -> (states[4 x M samples],
    elapsed[1 x M samples], q3[1 x M samples])``."""
    mapped = angles_function(samples, coefficients=coefficients, nodes=nodes).map(cases)
    return _native(mapped) if jit else mapped


def arcs_at_angles(x0, ac, alphas, angles, *, coefficients=EXACT, nodes=PANEL_NODES,
                   jit=False):
    """The paper's single first-order arc of M cases at angles given per case, one call.

    Parameters
    ----------
    x0 : array_like, shape (M, 4)
        Start states [r, theta, v_r, v_theta], canonical units.
    ac, alphas : array_like, shape (M,)
        Characteristic acceleration (canonical) and pitch (rad) per case.
    angles : sequence of array_like
        Case m's sample angles from its start (rad), increasing from 0; the cases may
        have different counts.
    coefficients, nodes, jit
        The thrust model, the time quadrature's Gauss-Legendre points per panel, and
        whether to compile (:func:`batch_function`).

    Returns
    -------
    list of (numpy.ndarray, numpy.ndarray)
        Per case, its states [r, theta, v_r, v_theta, t] at its angles (shape
        (5, len(angles[m])), the start first, t from 0 on the closed form's clock) and
        q3 at each angle after the start.
    """
    starts = np.asarray(x0, float).reshape(-1, 4)
    cases = starts.shape[0]
    counts = [len(a) for a in angles]
    width = max(counts)
    # Shorter arcs are padded with their last angle: empty panels (see angles_function).
    phis = np.array([np.r_[a, np.full(width - len(a), a[-1])] for a in angles], float)
    fun = angles_batch_function(width - 1, cases, coefficients=coefficients, nodes=nodes,
                                jit=jit)
    x5 = np.column_stack([starts, np.zeros(cases)])
    states, elapsed, q3 = fun(x5.T, np.broadcast_to(np.asarray(ac, float), (cases,))[None, :],
                              np.broadcast_to(np.asarray(alphas, float), (cases,))[None, :],
                              phis.reshape(1, -1))
    states = np.array(states).reshape(4, cases, width - 1)
    elapsed = np.array(elapsed).reshape(cases, width - 1)
    q3 = np.array(q3).reshape(cases, width - 1)
    out = []
    for m, count in enumerate(counts):
        xs = np.vstack([states[:, m, : count - 1], elapsed[m, : count - 1]])
        out.append((np.column_stack([x5[m], xs]), q3[m, : count - 1]))
    return out


@functools.lru_cache(maxsize=None)
def batch3d_function(segments, cases, *, samples=1, length_in="theta", coefficients=EXACT,
                     model=ArcModel(), jit=False):
    """``rectified3d.rectified3d_function`` mapped over ``cases``, laid out as
    :func:`batch_function`: ``(x0[9 x M], ac, alpha, delta, length [1 x M N each]) ->
    (xs[9 x M N S samples], q3[1 x M N S])``."""
    single = rectified3d_function(segments, samples=samples, length_in=length_in,
                                  coefficients=coefficients, model=model)
    mapped = single.map(cases)
    return _native(mapped) if jit else mapped


def propagate_batch3d(x0, quat0, alphas, deltas, lengths, ac, *, throttles=None, samples=1,
                      length_in="theta", coefficients=EXACT, model=ArcModel(), jit=False):
    """``rectified3d.propagate3d`` for M cases in one call.

    ``x0`` (4,) or (M, 4) and ``quat0`` (4,) or (M, 4) are the start polar states and
    planes; ``alphas``, ``deltas`` (rad) and ``lengths`` (angles or durations, as
    ``length_in``) (M, N) or (N,); ``ac`` scalar or (M,); the rest as
    :func:`propagate_batch`.  Returns ``xs`` of shape
    (M, 9, N S samples + 1) and ``q3`` of shape (M, N S).
    """
    n = np.shape(np.atleast_2d(alphas))[1]
    cases = max(np.atleast_2d(x0).shape[0], np.atleast_2d(quat0).shape[0], np.size(ac),
                *(np.shape(np.atleast_2d(v))[0] for v in (alphas, deltas, lengths)))
    rows = [_rows(v, cases, n, name) for v, name in (
        (alphas, "alphas"), (deltas, "deltas"), (lengths, "lengths"),
        (1.0 if throttles is None else throttles, "throttles"))]
    acs = np.broadcast_to(np.asarray(ac, float).reshape(-1, 1), (cases, 1))
    starts = np.column_stack([_rows(x0, cases, 4, "x0"), np.zeros(cases),
                              _rows(quat0, cases, 4, "quat0")])
    fun = batch3d_function(n, cases, samples=samples, length_in=length_in,
                           coefficients=coefficients, model=model, jit=jit)
    xs, q3 = fun(starts.T, (acs * rows[3]).reshape(1, -1),
                 *(row.reshape(1, -1) for row in rows[:3]))
    arcs = n * model.sub_arcs
    xs = np.array(xs).reshape(STATE, cases, arcs * samples).transpose(1, 0, 2)
    return (np.concatenate([starts[:, :, None], xs], axis=2),
            np.array(q3).reshape(cases, arcs))
