"""Many fixed-attitude cases propagated by the closed form in one mapped call.

A grid of propagations that differ only in their numbers (a survey, the paper's Figs. 3-4) is
one ``map`` over M cases of a single-case Function of :mod:`.rectified`, so each case is the
single-case propagator's answer to rounding.  Two shapes are batched: a rectified schedule of
N segments (:func:`batch_function`, :func:`propagate_batch`), and the paper's single
first-order arc at angles given per case (:func:`angles_batch_function`,
:func:`arcs_at_angles`), so that arcs of different sample counts share one call.

``jit`` compiles the batch to C.  Where the schedule is a plain chain of one SX arc, the C is
generated here across cases (:func:`_vectorised`): each CasADi instruction becomes one
operation on a vector of four or eight cases (GCC's vector extensions), the elementary
functions go to glibc's libmvec.  Its arithmetic is the scalar code's, rounded alike, but for
libmvec's sin, cos, log, atan and atan2 (within 4 ulp, not 1) and a shared divisor's
inverse (:data:`VECTOR_FLAGS`), which move ten-year states by a few 1e-13 of their size.
Elsewhere, or if that compile fails, the mapped Function's value
alone (derivatives would be far larger to compile) goes through ``propagation.compiled``,
which may leave it on CasADi's virtual machine.
"""

import functools
import logging
import os
import tempfile
from pathlib import Path

import casadi as ca
import numpy as np

from esail_opt.physics.thrust import EXACT
from esail_opt.propagation import compiled
from esail_opt.propagation.arcs import PANEL_NODES, ArcModel
from esail_opt.propagation.rectified import (angles_function, arc_function, flies_native,
                                             rectified_function, timed_arc_function)
from esail_opt.propagation.rectified3d import STATE, cartesian_function, rectified3d_function

log = logging.getLogger("esail_opt")

def _native(single, cases):
    """``single`` (one case) compiled to C, its value alone, through the disk cache, and
    mapped over ``cases``; on the virtual machine where compiling is off or failed.  The case
    is compiled, not the map, whose graph is slow to hash for the key.  A case that calls
    compiled arcs already is mapped as it is: its library could not find their symbols."""
    if any(f.class_name() == "External" for f in single.find_functions()):
        return single.map(cases)
    return compiled.compiled(single, with_derivatives=False).map(cases)


#: Where the vectorised batch's source and library live: the system's temporary folder,
#: as the working directory may be read-only.
_JIT_FOLDER = tempfile.gettempdir() + os.sep


#: Flags of the compile across cases: -march=native gives this CPU's vector width (with
#: a fallback without it); -ffp-contract=off rounds each product and sum as CasADi's
#: scalar code does (fused multiply-adds moved ten-year states by 5e-11 of their size);
#: -O3 without errno or traps gave the bits of -O1, a little faster; -freciprocal-math
#: divides once by a divisor an arc shares among many divisions and multiplies by its
#: inverse, within an ulp of each division, a shift of the size libmvec's functions make
#: (gain and shift measured in results/bench/README.md).
VECTOR_FLAGS = ("-O3", "-march=native", "-ffp-contract=off", "-fno-math-errno",
                "-fno-trapping-math", "-freciprocal-math")
#: The C of one arc over a vector of W cases (8 with AVX-512, 4 otherwise); M1/M2 call
#: libmvec where MVEC is defined, else the scalar function lane by lane; SPLAT keeps -0.0
#: and MASK gives 1.0 or 0.0, as CasADi's scalar code does.
_PRELUDE = r"""#include <math.h>
typedef long long int casadi_int;
#if defined(__AVX512F__)
#define W 8
#define V1(f) _ZGVeN8v_##f
#define V2(f) _ZGVeN8vv_##f
#elif defined(__AVX2__)
#define W 4
#define V1(f) _ZGVdN4v_##f
#define V2(f) _ZGVdN4vv_##f
#else
#define W 4
#undef MVEC
#endif
typedef double vd __attribute__((vector_size(8 * W)));
typedef long long vi __attribute__((vector_size(8 * W)));
#define SPLAT(c) ((c) - (vd){0})
#define MASK(m) ((vd)((m) & (vi)SPLAT(1.)))
#define LANES(t, e) for (int j = 0; j < W; ++j) t[j] = (e)
#ifdef MVEC
vd V1(sin)(vd); vd V1(cos)(vd); vd V1(log)(vd); vd V1(exp)(vd); vd V1(atan)(vd);
vd V2(atan2)(vd, vd); vd V2(pow)(vd, vd);
#define M1(f, t, a) t = V1(f)(a)
#define M2(f, t, a, b) t = V2(f)(a, b)
#else
#define M1(f, t, a) LANES(t, f(a[j]))
#define M2(f, t, a, b) LANES(t, f(a[j], b[j]))
#endif
"""
#: The batch over all cases, W at a time through the chained arcs; a last, partial
#: vector repeats the last case in its spare lanes.
_DRIVER = r"""
static const casadi_int s_x0[3] = {5, CASES, 1}, s_row[3] = {1, CASES * ARCS, 1};
static const casadi_int s_xs[3] = {5, CASES * ARCS * SAMPLES, 1};
casadi_int NAME_n_in(void) { return 4; }
casadi_int NAME_n_out(void) { return 2; }
const casadi_int* NAME_sparsity_in(casadi_int i) { return i == 0 ? s_x0 : s_row; }
const casadi_int* NAME_sparsity_out(casadi_int i) { return i == 0 ? s_xs : s_row; }
const char* NAME_name_in(casadi_int i) {
  static const char* names[4] = {"x0", "ac", "alpha", "length"};
  return i >= 0 && i < 4 ? names[i] : 0;
}
const char* NAME_name_out(casadi_int i) { return i == 0 ? "xs" : i == 1 ? "q3" : 0; }
int NAME_work(casadi_int* sz_arg, casadi_int* sz_res, casadi_int* sz_iw, casadi_int* sz_w) {
  *sz_arg = 4; *sz_res = 2; *sz_iw = 0; *sz_w = 0; return 0;
}
int NAME(const double** arg, double** res, casadi_int* iw, double* w, int mem) {
  vd x[5], in[3], xs[5 * SAMPLES], q3, spare;
  for (int b = 0; b < CASES; b += W) {
    int m[W];
    for (int j = 0; j < W; ++j) m[j] = b + j < CASES ? b + j : CASES - 1;
    for (int i = 0; i < 5; ++i)
      for (int j = 0; j < W; ++j) x[i][j] = arg[0] ? arg[0][5 * m[j] + i] : 0;
    for (int k = 0; k < ARCS; ++k) {
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < W; ++j) in[i][j] = arg[i + 1] ? arg[i + 1][m[j] * ARCS + k] : 0;
      arc(x, &in[0], &in[1], &in[2], xs, &q3, &spare);
      for (int j = 0; j < W && b + j < CASES; ++j) {
        int c = m[j] * ARCS + k;
        if (res[0])
          for (int s = 0; s < SAMPLES; ++s)
            for (int i = 0; i < 5; ++i) res[0][5 * (SAMPLES * c + s) + i] = xs[5 * s + i][j];
        if (res[1]) res[1][c] = q3[j];
      }
      for (int i = 0; i < 5; ++i) x[i] = xs[5 * (SAMPLES - 1) + i];
    }
  }
  return 0;
}
"""
#: CasADi's SX operations as vector expressions ({a}, {b} the operands' vectors).
_VECTOR_OPS = {
    ca.OP_ADD: "{a} + {b}", ca.OP_SUB: "{a} - {b}", ca.OP_MUL: "{a} * {b}",
    ca.OP_DIV: "{a} / {b}", ca.OP_NEG: "-{a}", ca.OP_SQ: "{a} * {a}", ca.OP_TWICE: "2. * {a}",
    ca.OP_INV: "1. / {a}", ca.OP_ASSIGN: "{a}", ca.OP_LT: "MASK({a} < {b})",
    ca.OP_LE: "MASK({a} <= {b})", ca.OP_EQ: "MASK({a} == {b})", ca.OP_NE: "MASK({a} != {b})",
    ca.OP_NOT: "MASK({a} == 0.)", ca.OP_IF_ELSE_ZERO: "(vd)((vi){b} & ({a} != 0.))",
}
#: Operations called lane by lane on CasADi's own scalar functions (the same numbers),
#: and those libmvec has as vector functions.
_LANE_CALLS = {ca.OP_SQRT: "sqrt", ca.OP_FABS: "fabs", ca.OP_TAN: "tan",
               ca.OP_FMIN: "fmin", ca.OP_FMAX: "fmax"}
_VECTOR_CALLS = {ca.OP_SIN: "sin", ca.OP_COS: "cos", ca.OP_LOG: "log", ca.OP_EXP: "exp",
                 ca.OP_ATAN: "atan", ca.OP_ATAN2: "atan2", ca.OP_POW: "pow",
                 ca.OP_CONSTPOW: "pow"}


def _vector_statement(fun, k):
    """Instruction ``k`` of the SX Function ``fun`` as one C statement on vectors."""
    op, args, out = fun.instruction_id(k), fun.instruction_input(k), fun.instruction_output(k)
    a, b = (f"w{args[n]}" if len(args) > n else "" for n in (0, 1))
    if op == ca.OP_INPUT:
        return f"w{out[0]} = in{args[0]}[{args[1]}];"
    if op == ca.OP_OUTPUT:
        return f"out{out[0]}[{out[1]}] = w{args[0]};"
    if op == ca.OP_CONST:
        return f"w{out[0]} = SPLAT({float(fun.instruction_constant(k))!r});"
    if op in _VECTOR_OPS:
        return f"w{out[0]} = " + _VECTOR_OPS[op].format(a=a, b=b) + ";"
    if op in _VECTOR_CALLS:
        return f"M{len(args)}({_VECTOR_CALLS[op]}, w{out[0]}, {', '.join((a, b)[:len(args)])});"
    if op in _LANE_CALLS:
        lanes = ", ".join(f"{x}[j]" for x in (a, b)[:len(args)])
        return f"LANES(w{out[0]}, {_LANE_CALLS[op]}({lanes}));"
    raise NotImplementedError(f"CasADi operation {op}")


def vector_source(arc, segments, cases, name):
    """C of ``segments`` chained arcs of the SX Function ``arc`` ``(x0[5], ac, alpha,
    length) -> (xs[5 x S], q3[1], ...)`` over ``cases`` cases, as a CasADi external
    Function ``name`` with the inputs and outputs of :func:`batch_function`'s map."""
    if arc.size_in(0) != (5, 1) or arc.nnz_out(1) != 1 or arc.n_out() > 3:
        raise NotImplementedError(f"{arc.name()} is not an arc of the chain")
    outs = ", ".join(f"vd* out{i}" for i in range(3))
    body = "\n  ".join(_vector_statement(arc, k) for k in range(arc.n_instructions()))
    work = ", ".join(f"w{i}" for i in range(arc.sz_w()))
    text = (_PRELUDE + f"static void arc(const vd* in0, const vd* in1, const vd* in2, "
            f"const vd* in3, {outs}) {{\n  vd {work};\n  {body}\n}}\n" + _DRIVER)
    for key, value in (("CASES", cases), ("ARCS", segments),
                       ("SAMPLES", arc.size2_out(0)), ("NAME", name)):
        text = text.replace(key, str(value))
    return text


def _plain_arc(samples, length_in, coefficients, model):
    """The arc that :func:`batch_function`'s schedule chains, as one SX Function, or
    None where the schedule is more than a chain of it."""
    if model.sub_arcs != 1 or model.extrapolate:
        return None
    one = model.one_arc()
    if flies_native(coefficients=coefficients, model=one, length_in=length_in):
        return None
    make = timed_arc_function if length_in == "time" else arc_function
    arc = make(samples, coefficients=coefficients, model=one)
    # An arc in theta is an MX map of SX panels.
    return arc if arc.class_name() == "SXFunction" else arc.expand()


def _vectorised(arc, segments, cases):
    """:func:`vector_source` compiled and loaded, with libmvec and -march=native if they
    work; None when compiling is off or every try fails (one warning)."""
    if not compiled.enabled():
        return None
    name = f"lanes_{segments}x{cases}"
    failure = None
    for flags, libraries in ((VECTOR_FLAGS, ("-lmvec", "-lm")),
                             (VECTOR_FLAGS[:1] + VECTOR_FLAGS[2:], ("-lm",))):
        defines = ["-DMVEC"] if "-lmvec" in libraries else []
        with tempfile.NamedTemporaryFile("w", suffix=".c", dir=_JIT_FOLDER,
                                         prefix="esail_opt_lanes_", delete=False) as out:
            out.write(vector_source(arc, segments, cases, name))
        try:
            importer = ca.Importer(out.name, "shell", {
                "flags": [*flags, *defines], "linker_flags": list(libraries),
                "directory": _JIT_FOLDER, "verbose": False})
            return ca.external(name, importer)
        except RuntimeError as err:
            failure = str(err).strip().splitlines()[-1]
        finally:
            Path(out.name).unlink(missing_ok=True)
    log.warning("esail-opt: compiling the batch across cases failed (%s); it is compiled "
                "case by case", failure)
    return None


@functools.lru_cache(maxsize=None)
def batch_function(segments, cases, *, samples=1, length_in="theta", coefficients=EXACT,
                   model=ArcModel(), jit=False, across_cases=True):
    """``rectified.rectified_function`` (same arguments) mapped over ``cases``:
    ``(x0[5 x M], ac[1 x M N], alpha[1 x M N], length[1 x M N]) ->
    (xs[5 x M N S samples], q3[1 x M N S])``, S = ``model.sub_arcs``, case m's columns the
    m-th block of each; with ``jit`` compiled to C (see the module's docstring), across cases
    unless ``across_cases`` is False."""
    single = rectified_function(segments, samples=samples, length_in=length_in,
                                coefficients=coefficients, model=model)
    if not jit:
        return single.map(cases)
    arc = _plain_arc(samples, length_in, coefficients, model) if across_cases else None
    fast = None if arc is None else _vectorised(arc, segments, cases)
    return _native(single, cases) if fast is None else fast


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

    ``x0`` (4,) or (M, 4) are the polar start states, canonical; ``alphas`` (rad),
    ``lengths`` (as ``length_in``) and ``throttles`` (default 1) are (M, N), or a (N,) row
    for every case; ``ac`` is canonical, scalar or (M,); ``jit`` compiles the map (see the
    module's docstring); the rest as :func:`rectified.propagate`.  Returns ``xs`` (M, 5,
    N S samples + 1), each case's [r, theta, v_r, v_theta, t] at its start and every
    sample (S = ``model.sub_arcs``), and ``q3`` (M, N S), the margin at each arc's end.
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
    single = angles_function(samples, coefficients=coefficients, nodes=nodes)
    return _native(single, cases) if jit else single.map(cases)


def arcs_at_angles(x0, ac, alphas, angles, *, coefficients=EXACT, nodes=PANEL_NODES,
                   jit=False):
    """The paper's single first-order arc of M cases at angles given per case, one call.

    ``x0`` (M, 4) are the start states, canonical; ``ac`` (canonical) and ``alphas`` (rad) are
    (M,); ``angles[m]`` are case m's sample angles from its start (rad, increasing from 0,
    counts may differ); ``nodes`` are the Gauss-Legendre points per panel.  Returns per case
    its states [r, theta, v_r, v_theta, t] at its angles (5, len(angles[m])), t from 0 on the
    closed form's clock, and q3 at each angle after the start.
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
                     model=ArcModel(), jit=False, cartesian=False):
    """``rectified3d.rectified3d_function`` mapped over ``cases``, laid out as
    :func:`batch_function`: ``(x0[9 x M], ac, alpha, delta, length [1 x M N each]) ->
    (xs[9 x M N S samples], q3[1 x M N S])``; with ``cartesian`` a third output, every
    sample's Cartesian state and time (7 x M N S samples), converted in the same call."""
    single = rectified3d_function(segments, samples=samples, length_in=length_in,
                                  coefficients=coefficients, model=model)
    if cartesian:
        symbols = [ca.MX.sym(single.name_in(k), single.sparsity_in(k))
                   for k in range(single.n_in())]
        xs, q3 = single(*symbols)
        states = cartesian_function().map(xs.shape[1])(xs)
        single = ca.Function(f"{single.name()}_cartesian", symbols, [xs, q3, states],
                             single.name_in(), [*single.name_out(), "cartesian"])
    return _native(single, cases) if jit else single.map(cases)


def propagate_batch3d(x0, quat0, alphas, deltas, lengths, ac, *, throttles=None, samples=1,
                      length_in="theta", coefficients=EXACT, model=ArcModel(), jit=False):
    """``rectified3d.propagate3d`` for M cases in one call, as :func:`propagate_batch` with
    ``quat0`` (4,) or (M, 4) the start planes and ``deltas`` (rad) as ``alphas``.  Returns
    ``xs`` (M, 9, N S samples + 1) and ``q3`` (M, N S)."""
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
