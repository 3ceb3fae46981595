"""CasADi Functions stored on disk (``function_store``): the closed form's SX Functions
(``propagation.graph_store``) and the bodies' splines (``bodies.track``).  Read back they
are the Functions built, and anything that could make them differ builds anew."""

import inspect
import logging
import os

import casadi as ca
import numpy as np

from esail_opt.physics.thrust import EXACT
from esail_opt.propagation import graph_store
from esail_opt.propagation.rectified import end_function


def _counted(builds):
    """The raw second-order arc builder (under its process cache and its store),
    counting its calls in ``builds``."""
    raw = end_function.__wrapped__.__wrapped__

    def builder(**kwargs):
        builds.append(kwargs)
        return raw(**kwargs)

    builder.__name__ = raw.__name__
    builder.__signature__ = inspect.signature(raw)
    return builder


def _outputs(fun):
    x0 = np.array([1.0, 0.3, 0.02, 0.98, 0.0])
    return [np.array(v) for v in fun(x0, 0.03, 0.4, 1.7)]


def test_a_stored_arc_reads_back_as_the_graph_built(tmp_path, monkeypatch):
    monkeypatch.setenv("ESAIL_OPT_CACHE", str(tmp_path))
    builds = []
    store = graph_store.stored(_counted(builds))
    built = store()
    read = store()
    assert len(builds) == 1  # the second call read the file
    assert read.serialize() == built.serialize()
    for a, b in zip(_outputs(read), _outputs(built)):
        np.testing.assert_array_equal(a, b)
    # The defaults named explicitly are the same graph, so the same file.
    store(coefficients=EXACT)
    assert len(builds) == 1
    assert len(list((tmp_path / "graphs").glob("*.casadi"))) == 1


def test_other_arguments_or_other_sources_build_anew(tmp_path, monkeypatch):
    monkeypatch.setenv("ESAIL_OPT_CACHE", str(tmp_path))
    builds = []
    store = graph_store.stored(_counted(builds))
    store()
    store(nodes=3)
    assert len(builds) == 2
    monkeypatch.setattr(graph_store, "source_digest", lambda: "an edited closed form")
    store()
    assert len(builds) == 3
    assert len(list((tmp_path / "graphs").glob("*.casadi"))) == 3


def test_the_sources_cover_the_closed_form_and_its_builders():
    names = {path.name for path in graph_store.SOURCES}
    assert {"closed_form.py", "thrust.py", "constants.py", "dynamics.py", "arcs.py",
            "rectified.py"} <= names
    assert all(path.is_file() for path in graph_store.SOURCES)


def test_a_damaged_graph_is_built_again_and_rewritten(tmp_path, monkeypatch):
    monkeypatch.setenv("ESAIL_OPT_CACHE", str(tmp_path))
    builds = []
    store = graph_store.stored(_counted(builds))
    built = store()
    (path,) = (tmp_path / "graphs").glob("*.casadi")
    text = path.read_text()
    path.write_text(text[: len(text) // 2])  # a write cut short
    again = store()
    assert len(builds) == 2
    assert again.serialize() == built.serialize()
    assert path.read_text() == text
    store()  # the rewritten file is read
    assert len(builds) == 2


def test_an_unwritable_cache_still_builds(tmp_path, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("ESAIL_OPT_CACHE", str(blocker / "cache"))
    builds = []
    store = graph_store.stored(_counted(builds))
    first, second = store(), store()
    assert len(builds) == 2
    assert first.serialize() == second.serialize()


def test_a_stored_graph_follows_the_umask(tmp_path, monkeypatch):
    monkeypatch.setenv("ESAIL_OPT_CACHE", str(tmp_path))
    old = os.umask(0o022)
    try:
        graph_store.stored(_counted([]))()
    finally:
        os.umask(old)
    (path,) = (tmp_path / "graphs").glob("*.casadi")
    assert path.stat().st_mode & 0o777 == 0o644
    assert not list((tmp_path / "graphs").glob(".*.tmp"))


def test_a_graph_failing_its_checksum_is_said_in_one_line(tmp_path, monkeypatch, caplog):
    """The README's promise: a stored arc graph that fails its checksum is rebuilt with
    one line naming it; an intact one is read without a word."""
    monkeypatch.setenv("ESAIL_OPT_CACHE", str(tmp_path))
    builds = []
    store = graph_store.stored(_counted(builds))
    store()
    (path,) = (tmp_path / "graphs").glob("*.casadi")
    text = path.read_text()
    path.write_text(text[:-10] + "0123456789")  # same length, other bytes
    with caplog.at_level(logging.WARNING, logger="esail_opt"):
        store()
        store()
    lines = [r.getMessage() for r in caplog.records]
    assert len(builds) == 2
    assert len(lines) == 1 and path.name in lines[0] and "checksum" in lines[0], lines


def test_a_stored_spline_is_the_spline_fitted(tmp_path, monkeypatch):
    """A body track's spline read back from the store (``bodies.track.stored_spline``)
    gives casadi.interpolant's fit, value and derivatives, to the bit; other samples
    fit anew into a file of their own."""
    from esail_opt.bodies import track

    monkeypatch.setenv("ESAIL_OPT_CACHE", str(tmp_path))
    grid = np.linspace(0.0, 3.0, 41)
    values = np.sin(3 * grid) + grid**2
    fits = []
    interpolant = ca.interpolant

    def counted(*args):
        fits.append(args[0])
        return interpolant(*args)

    monkeypatch.setattr(track.ca, "interpolant", counted)
    first = track.stored_spline("probe", grid, values)
    again = track.stored_spline("probe", grid, values)
    assert fits == ["probe"]  # the second was read from its file
    other = track.stored_spline("probe", grid, 2 * values)
    assert fits == ["probe", "probe"]
    monkeypatch.setattr(track.ca, "interpolant", interpolant)
    fitted = ca.interpolant("probe", "bspline", [grid], values)
    t = ca.MX.sym("t")
    x = np.linspace(-0.2, 3.2, 301).reshape(1, -1)

    def evaluated(spline):
        value = spline(t)
        slope = ca.jacobian(value, t)
        curvature = ca.jacobian(slope, t)
        return np.array(ca.Function("f", [t], [value, slope, curvature]).map(x.size)(x))

    for spline in (first, again):
        np.testing.assert_array_equal(evaluated(spline), evaluated(fitted))
    np.testing.assert_array_equal(np.array(other(x)), 2 * np.array(fitted(x)))
    assert len(list((tmp_path / "tracks").glob("*.casadi"))) == 2


def test_stored_samples_are_the_sources_and_follow_a_changed_source(tmp_path, monkeypatch,
                                                                     caplog):
    """A track's samples read back from the store (``bodies.track.stored_samples``) are
    the source's own numbers; a source that gives other numbers at the spot dates is
    sampled afresh, as is a damaged file (with one line); other dates get a file of
    their own."""
    from esail_opt.bodies import track

    monkeypatch.setenv("ESAIL_OPT_CACHE", str(tmp_path))
    calls = []

    def source(jd, scale=1.0):
        calls.append(np.size(jd))
        return scale * np.vstack([np.sin(jd), np.cos(jd)])

    jd = np.linspace(2451545.0, 2452545.0, 101)
    first = track.stored_samples("probe", source, jd)
    np.testing.assert_array_equal(first, source(jd))
    calls.clear()
    again = track.stored_samples("probe", source, jd)
    np.testing.assert_array_equal(again, first)
    assert calls == [3]  # the spot dates only
    changed = track.stored_samples("probe", lambda at: source(at, 1 + 1e-15), jd)
    np.testing.assert_array_equal(changed, source(jd, 1 + 1e-15))
    (path,) = (tmp_path / "tracks").glob("probe-*.npy")
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with caplog.at_level(logging.WARNING, logger="esail_opt"):
        healed = track.stored_samples("probe", source, jd)
    np.testing.assert_array_equal(healed, source(jd))
    assert len(caplog.records) == 1 and "checksum" in caplog.records[0].getMessage()
    track.stored_samples("probe", source, jd[:50])
    assert len(list((tmp_path / "tracks").glob("probe-*.npy"))) == 2


def test_stored_errors_are_the_measured_ones_and_follow_other_samples(tmp_path, monkeypatch):
    """A track's largest errors read back from the store (``bodies.track.stored_errors``)
    are the ones measured; other samples, or exact states that changed, are measured
    afresh; a real track built twice has the same errors, the second time from the
    store."""
    from esail_opt.bodies import track

    monkeypatch.setenv("ESAIL_OPT_CACHE", str(tmp_path))
    measured = []

    def measure(value):
        def run():
            measured.append(value)
            return value, value / 1e4
        return run

    grid, exact = np.linspace(0.0, 1.0, 11), np.arange(22.0).reshape(2, 11)
    assert track.stored_errors("probe_error", (grid, exact), measure(0.5)) == (0.5, 5e-5)
    assert track.stored_errors("probe_error", (grid, exact), measure(9.0)) == (0.5, 5e-5)
    assert measured == [0.5]
    assert track.stored_errors("probe_error", (grid, exact + 1e-15 * exact),
                               measure(0.7)) == (0.7, 7e-5)
    assert track.stored_errors("probe_error", (grid[:-1], exact), measure(0.8))[0] == 0.8
    assert measured == [0.5, 0.7, 0.8]

    built = track.track_of("mars", 2461000.5, 2461400.5)
    assert list((tmp_path / "tracks").glob("track_mars_error-*.npy"))
    calls = []
    monkeypatch.setattr(track, "_cartesian", lambda polar: calls.append(1) or polar)
    again = track.track_of("mars", 2461000.5, 2461400.5)
    assert calls == []  # not measured again: read back
    assert (again.max_error_km, again.max_error_m_s) == (built.max_error_km,
                                                         built.max_error_m_s)
    assert 0 < built.max_error_km < track.TARGET_ERROR_KM
