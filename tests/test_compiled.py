"""The compiled-code cache: compiled arcs agree with the virtual machine, a library is
built once per kind and reused across processes, and every failure falls back to the
virtual machine with one line (``esail_opt.propagation.compiled``)."""

import logging
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from conftest import solved_under
from esail_opt.propagation import compiled as cc
from esail_opt.propagation.arcs import ArcModel
from esail_opt.propagation.rectified import panel_function

#: A representative panel input: an eccentric start (e ~ 0.1), a~_c ~ 0.17, 40 deg pitch,
#: a panel from 0.2 to 0.9 rad.
POINT = [np.array([1.1, 0.3, 0.05, 0.98, 2.0]), 0.17, 0.7, 0.2, 0.9]


def _fresh(monkeypatch, folder, **env):
    """Point the cache at ``folder`` with ``env`` set, and forget what this process loaded."""
    monkeypatch.setenv("ESAIL_OPT_CACHE", str(folder))
    monkeypatch.delenv("ESAIL_OPT_COMPILE", raising=False)
    for name, value in env.items():
        monkeypatch.setenv(name, value)
    monkeypatch.setattr(cc, "_loaded", {})
    cc._compiler_identity.cache_clear()


def _numbers(fun, args):
    return [np.array(v) for v in fun.call(list(args))]


@pytest.fixture(scope="module")
def shared_cache(tmp_path_factory):
    return tmp_path_factory.mktemp("cache")


def test_compiled_panel_and_its_derivatives_match_the_virtual_machine(monkeypatch,
                                                                       shared_cache):
    _fresh(monkeypatch, shared_cache)
    panel = panel_function()
    fast = cc.compiled(panel)
    assert fast is not panel and fast.class_name() == "External"
    pairs = [(panel, fast), (panel.jacobian(), fast.jacobian()),
             (panel.reverse(1), fast.reverse(1)),
             (panel.reverse(1).jacobian(), fast.reverse(1).jacobian())]
    rng = np.random.default_rng(3)
    for slow, quick in pairs:
        args = [np.asarray(POINT[i], float) if i < len(POINT)
                else rng.standard_normal(slow.size_in(i)) for i in range(slow.n_in())]
        for a, b in zip(_numbers(slow, args), _numbers(quick, args)):
            assert a.shape == b.shape
            assert np.allclose(a, b, rtol=1e-12, atol=1e-13), (slow.name(), a, b)
    assert list(shared_cache.glob("*.so")), "the library is in the cache"
    assert not list(shared_cache.glob(".build-*")), "no build directory is left behind"


def _child(folder, extra=""):
    code = textwrap.dedent(f"""
        import logging, os
        os.environ["ESAIL_OPT_CACHE"] = {str(folder)!r}
        logging.basicConfig(level=logging.INFO, format="%(message)s")
        from esail_opt.propagation.compiled import compiled
        from esail_opt.propagation.rectified import panel_function
        {extra}
        fun = compiled(panel_function())
        print(fun.class_name())
    """)
    env = {k: v for k, v in os.environ.items() if k != "ESAIL_OPT_COMPILE"}
    return subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env)


def test_a_second_process_loads_the_cached_library_without_compiling(monkeypatch,
                                                                    shared_cache):
    _fresh(monkeypatch, shared_cache)
    cc.compiled(panel_function())  # built by the test above, or here
    (library,) = shared_cache.glob("*.so")
    stamp = library.stat().st_mtime_ns
    out, err = _child(shared_cache).communicate(timeout=120)
    assert out.strip() == "External"
    assert "compiling" not in err
    assert library.stat().st_mtime_ns == stamp


def test_parallel_processes_compile_one_library(tmp_path):
    children = [_child(tmp_path) for _ in range(2)]
    outputs = [child.communicate(timeout=600) for child in children]
    assert [child.returncode for child in children] == [0, 0]
    assert [out.strip() for out, _ in outputs] == ["External", "External"]
    assert sum(err.count("compiling") for _, err in outputs) == 1
    assert len(list(tmp_path.glob("*.so"))) == 1
    assert not list(tmp_path.glob(".build-*"))


def test_the_switch_forces_the_virtual_machine_silently(monkeypatch, tmp_path, caplog):
    _fresh(monkeypatch, tmp_path / "cache", ESAIL_OPT_COMPILE="0")
    panel = panel_function()
    with caplog.at_level(logging.INFO, logger="esail_opt"):
        assert cc.compiled(panel) is panel
    assert not caplog.records
    assert not (tmp_path / "cache").exists()


def test_no_compiler_falls_back_with_one_line(monkeypatch, tmp_path, caplog):
    _fresh(monkeypatch, tmp_path / "cache", CC=str(tmp_path / "no-such-cc"))
    panel = panel_function()
    with caplog.at_level(logging.INFO, logger="esail_opt"):
        assert cc.compiled(panel) is panel
    assert [r.levelname for r in caplog.records] == ["WARNING"]
    assert "no C compiler" in caplog.records[0].getMessage()


def test_a_failed_compile_falls_back_and_leaves_no_library(monkeypatch, tmp_path, caplog):
    broken = tmp_path / "broken-cc"
    broken.write_text("#!/bin/sh\n[ \"$1\" = --version ] && { echo broken 1.0; exit 0; }\n"
                      "echo 'fatal: out of luck' >&2\nexit 1\n")
    broken.chmod(0o755)
    _fresh(monkeypatch, tmp_path / "cache", CC=str(broken))
    panel = panel_function()
    with caplog.at_level(logging.INFO, logger="esail_opt"):
        assert cc.compiled(panel) is panel
    warnings = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
    assert len(warnings) == 1 and "out of luck" in warnings[0]
    assert not list((tmp_path / "cache").glob("*.so"))
    assert not list((tmp_path / "cache").glob(".build-*"))


#: A segment's input: an eccentric start, a~_c ~ 0.17, -34 deg pitch, 0.8 rad.
SEGMENT_POINT = [np.array([0.9, 0.4, 0.08, 1.1, 3.0]), 0.17, -0.6, 0.8]


def _segment_pairs(fast, slow):
    """(fast, slow) pairs of a segment Function, its Jacobian and its Hessian block."""
    return [(fast, slow), (fast.jacobian(), slow.jacobian()),
            (fast.reverse(1).jacobian(), slow.reverse(1).jacobian())]


def _agree(fast, slow, rtol):
    rng = np.random.default_rng(5)
    nominal = [np.array(v) for v in slow.call(SEGMENT_POINT)]
    for f, s in _segment_pairs(fast, slow):
        args = (SEGMENT_POINT + nominal)[:f.n_in()]
        args += [rng.standard_normal(f.size_in(i)) for i in range(len(args), f.n_in())]
        for a, b in zip(_numbers(f, args), _numbers(s, args)):
            assert a.shape == b.shape
            assert np.allclose(a, b, rtol=rtol, atol=1e-13), (f.name(), a, b)


def test_compiled_segment_is_the_expanded_segment_with_its_derivatives():
    """The NLP's segment over compiled arcs (its own graph compiled too) against the
    expanded SX one: values, Jacobians and Hessian blocks on an eccentric start,
    Richardson and plain."""
    from esail_opt.optimisation.segment_methods import closed_form_segment

    for extrapolate in (True, False):
        fast = closed_form_segment(model=ArcModel(sub_arcs=3, extrapolate=extrapolate))
        slow = closed_form_segment(model=ArcModel(sub_arcs=3, extrapolate=extrapolate,
                                                  native=False))
        assert fast.class_name() == "External" and slow.is_a("SXFunction")
        _agree(fast, slow, 1e-11)


def _graph_on_the_virtual_machine(monkeypatch):
    """Compile the arcs but leave the segment's graph of arc calls on the virtual
    machine (what a failed compile of the graph leaves), with fresh segment caches."""
    from esail_opt.optimisation import segment_methods

    real = cc.compiled
    monkeypatch.setattr(cc, "compiled", lambda fun, calls=(): fun if calls else real(fun))
    segment_methods.closed_form_segment.cache_clear()
    monkeypatch.setattr(segment_methods, "closed_form_segment",
                        segment_methods.closed_form_segment.__wrapped__)


def test_compiled_segment_graph_matches_its_virtual_machine_graph(monkeypatch):
    """The segment's library (its graph of arc calls as C, linked against the arcs')
    against the same graph run by CasADi's virtual machine."""
    from esail_opt.optimisation import segment_methods

    fast = segment_methods.closed_form_segment(model=ArcModel(sub_arcs=2))
    _graph_on_the_virtual_machine(monkeypatch)
    slow = segment_methods.closed_form_segment(model=ArcModel(sub_arcs=2))
    assert fast.class_name() == "External" and slow.is_a("MXFunction")
    _agree(fast, slow, 1e-12)


def test_both_paths_solve_one_small_case_alike(monkeypatch):
    """One small transfer solved on compiled arcs and on CasADi's virtual machine:
    the same optimum, in the same iterations."""
    import esail_opt as eo

    problem = eo.Problem(
        name="small", departure=eo.ParkingOrbit(1.0), sail=eo.Sail(1.0),
        segments=eo.Segments(8, 2), objective=eo.MinTime(), target=eo.CircularOrbit(0.8))
    results = solved_under(monkeypatch, "ESAIL_OPT_COMPILE", ("1", "0"), problem)
    fast, slow = results["1"], results["0"]
    assert fast.status == slow.status == "Solve_Succeeded"
    assert fast.iterations == slow.iterations
    assert fast.objective == pytest.approx(slow.objective, rel=1e-9)
    np.testing.assert_allclose(fast.alpha, slow.alpha, atol=1e-6)


def test_compiled_segment_graph_solves_like_its_virtual_machine_graph(monkeypatch):
    """The same small transfer with the segment's graph compiled and on the virtual
    machine (arcs compiled in both): the same optimum in the same iterations."""
    import esail_opt as eo
    from esail_opt.optimisation.ipopt import solve_problem

    problem = eo.Problem(
        name="small", departure=eo.ParkingOrbit(1.0), sail=eo.Sail(1.0),
        segments=eo.Segments(8, 2), objective=eo.MinTime(), target=eo.CircularOrbit(0.8))
    monkeypatch.delenv("ESAIL_OPT_COMPILE", raising=False)
    fast = solve_problem(problem)[0]
    _graph_on_the_virtual_machine(monkeypatch)
    slow = solve_problem(problem)[0]
    assert fast.status == slow.status == "Solve_Succeeded"
    assert fast.iterations == slow.iterations
    assert fast.objective == pytest.approx(slow.objective, rel=1e-10)
    np.testing.assert_allclose(fast.alpha, slow.alpha, atol=1e-7)


def test_a_failed_compile_of_the_segment_graph_keeps_it_on_compiled_arcs(monkeypatch,
                                                                         shared_cache, caplog):
    """When the arcs compile but the segment's library does not link, the segment is its
    MX graph over the compiled arcs, with one warning."""
    from esail_opt.optimisation import segment_methods

    _fresh(monkeypatch, shared_cache)
    real = cc._build

    def build(fun, compiler, target, links=(), *rest):
        if links:
            raise subprocess.CalledProcessError(1, compiler, stderr="ld: out of luck\n")
        return real(fun, compiler, target, links, *rest)

    monkeypatch.setattr(cc, "_build", build)
    monkeypatch.setattr(segment_methods, "closed_form_segment",
                        segment_methods.closed_form_segment.__wrapped__)
    with caplog.at_level(logging.WARNING, logger="esail_opt"):
        segment = segment_methods.closed_form_segment(model=ArcModel(sub_arcs=1))
    assert segment.is_a("MXFunction")
    assert [r.getMessage() for r in caplog.records if "out of luck" in r.getMessage()]
    assert not list(shared_cache.glob("segment-*.so"))
    assert not list(shared_cache.glob(".build-*"))
