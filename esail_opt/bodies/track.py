"""A smooth, twice-differentiable form of a body's state over a time window, for the NLP.

Ipopt uses exact Hessians, so a body's polar state must be a CasADi expression of a free date, which
neither DE421's Chebyshev records (joined only approximately smoothly) nor the iterated Kepler
solver is.  A :class:`Track` samples the exact source on a uniform grid over the window plus a
margin (where a spline is least accurate and an iterate may stray), unwraps the longitude and fits a
C2 cubic B-spline (``casadi.interpolant``, "bspline", not-a-knot) to r, theta, v_r and v_theta.
Small bodies too: one form keeps one contract, and its error is far below the Keplerian model's.
"""

import math

import casadi as ca
import numpy as np

from esail_opt.runtime import function_store
from esail_opt.bodies import ephemeris
from esail_opt.bodies.dates import iso_from_jd, jd_from_tu, tu_from_jd
from esail_opt.bodies.keplerian import SmallBody
from esail_opt.errors import InputError, check_range
from esail_opt.physics import constants as units

#: Samples per osculating period in the default step.
SAMPLES_PER_PERIOD = 200
#: Margin sampled beyond each end of the window: this many steps, and at least
#: MARGIN_DAYS, so that an NLP iterate a little outside the window still sees the body.
MARGIN_STEPS = 4
MARGIN_DAYS = 60.0
#: At least this many steps across the window, however short it is.
MIN_STEPS = 16
#: The default step is halved until the measured error is below both of these.
TARGET_ERROR_KM = 0.05
TARGET_ERROR_M_S = 1e-4
MAX_HALVINGS = 6


class Track:
    """A body's polar state over a time window as a smooth CasADi function; see :func:`track_of`.

    Attributes: ``name``; ``jd_range``, the window's (start, stop) Julian dates (TDB), and
    ``t_range``, the same in TU since J2000 TDB; ``step_days``, the samples' spacing, days;
    ``sampled_jd``, the dates sampled, (M,), over ``sampled_t_range`` (:attr:`t_range` widened by
    the margin, less where a planet's window meets the ephemeris span); ``samples``, the polar
    states fitted, (4, M), theta unwrapped; ``max_error_km`` and ``max_error_m_s``, the largest
    in-plane position (km) and velocity (m/s) difference from the exact source at the samples'
    mid-points within :attr:`t_range`; ``function``, ``track(t) -> [r, theta, v_r, v_theta]`` (4x1,
    t in TU since J2000, theta unwrapped), which holds the end state beyond ``sampled_t_range``
    (zero derivative): bound t to :attr:`t_range` in the NLP.
    """

    def __init__(self, name, source, start_jd, stop_jd, step_days, span=None):
        self.name = name
        self.jd_range = (float(start_jd), float(stop_jd))
        self.t_range = (tu_from_jd(start_jd), tu_from_jd(stop_jd))
        self.step_days = float(step_days)
        margin = max(MARGIN_STEPS * step_days, MARGIN_DAYS)
        low, high = start_jd - margin, stop_jd + margin
        if span is not None:
            low, high = max(low, span[0]), min(high, span[1])
        count = max(int(math.ceil((high - low) / step_days)), MIN_STEPS) + 1
        jd = np.linspace(low, high, count)
        polar = stored_samples(self._tag(), lambda at: source(at)[0], jd)
        polar[1] = np.unwrap(polar[1])
        t_grid = tu_from_jd(jd)
        t = ca.MX.sym("t")
        # CasADi's B-spline is zero outside its knots: a stray iterate gets the end state.
        held = ca.fmin(ca.fmax(t, t_grid[0]), t_grid[-1])
        # Four outputs in one spline (sample index slowest): the same fit, far cheaper.
        spline = stored_spline(self._tag(), t_grid, polar.T.ravel())
        self.function = ca.Function("track", [t], [spline(held)], ["t"], ["polar"])
        self.sampled_t_range = (float(t_grid[0]), float(t_grid[-1]))
        self.sampled_jd = jd
        self.samples = polar
        self._measure(source, jd, polar)

    def _tag(self):
        words = "".join(c if c.isalnum() else " " for c in self.name).split()
        return "track_" + "_".join(words).lower()

    def polar(self, t):
        """The smooth polar state ``[r, theta_unwrapped, v_r, v_theta]`` at canonical time(s) t (TU
        since J2000 TDB): shape (4,) or (4, M) for a float or array, which must lie in
        :attr:`t_range` (InputError otherwise), a 4x1 CasADi expression for a symbolic t."""
        if isinstance(t, (ca.SX, ca.MX)):
            return self.function(t)
        times = np.asarray(t, dtype=float)
        self._check_times(times)
        flat = np.atleast_1d(times).ravel()
        values = np.array(self.function.map(flat.size)(flat.reshape(1, -1)))
        return values[:, 0] if times.ndim == 0 else values

    def _check_times(self, times):
        first, last = self.t_range
        slack = 1e-9 * max(1.0, abs(first), abs(last))
        bad = ~((times >= first - slack) & (times <= last + slack))
        if np.any(bad):
            worst = float(np.atleast_1d(times)[np.atleast_1d(bad)][0])
            when = (f"on {iso_from_jd(jd_from_tu(worst))} TDB" if math.isfinite(worst)
                    else f"at t = {worst!r}")
            # Reached by a flight, not a date the user wrote: say which dates would fit.
            raise InputError(
                f"{self.name} is needed {when}, outside the dates it is known at "
                f"[{iso_from_jd(self.jd_range[0])}, {iso_from_jd(self.jd_range[1])}] TDB: "
                "depart earlier, shorten the flight or bound the arrival (arrival_window)"
            )

    def _measure(self, source, jd_grid, fitted_to):
        mids = _mids(jd_grid, self.jd_range)
        exact = stored_samples(self._tag() + "_mids", lambda at: source(at)[0], mids)

        def measure():
            fitted = np.array(self.function.map(mids.size)(tu_from_jd(mids).reshape(1, -1)))
            dx, dy, dvx, dvy = _cartesian(fitted) - _cartesian(exact)
            return (units.length_to_km(np.hypot(dx, dy).max()),
                    units.speed_to_m_s(np.hypot(dvx, dvy).max()))

        self.max_error_km, self.max_error_m_s = stored_errors(
            self._tag() + "_error", (jd_grid, fitted_to, mids, exact), measure)

    def __repr__(self):
        return (f"Track({self.name!r}, {iso_from_jd(self.jd_range[0])} .. "
                f"{iso_from_jd(self.jd_range[1])}, step {self.step_days:.3g} d, "
                f"max error {self.max_error_km:.3g} km, {self.max_error_m_s:.3g} m/s)")


def stored_spline(name, grid, values):
    """``casadi.interpolant(name, "bspline", [grid], values)``, read from the package's cache
    (:mod:`esail_opt.runtime.function_store`) when the same samples were fitted before with this
    CasADi version, since fitting is most of building a track."""
    grid = np.ascontiguousarray(grid, dtype=float)
    values = np.ascontiguousarray(values, dtype=float)
    decided_by = b"\0".join([name.encode(), ca.__version__.encode(), grid.tobytes(),
                             values.tobytes()])
    return function_store.kept(function_store.path_of("tracks", name, decided_by),
                               lambda: ca.interpolant(name, "bspline", [grid], values))


#: Dates at which a stored sampling is checked against its source before it is used.
SPOT_CHECKS = 3


def stored_samples(name, source, jd):
    """``source(jd)`` (an array whose last axis runs over ``jd``), read from the package's cache
    when the same dates of ``name`` were sampled before (sampling is most of what is left of
    building a track), but only if the source gives exactly them again at :data:`SPOT_CHECKS` of the
    dates, so that a changed ephemeris, set of elements or conversion is sampled afresh."""
    jd = np.ascontiguousarray(jd, dtype=float)
    path = function_store.path_of("tracks", name, b"\0".join([name.encode(), jd.tobytes()]),
                                  suffix=".npy")
    spots = np.unique(np.linspace(0, jd.size - 1, SPOT_CHECKS).round().astype(int))
    stored = function_store.read_array(path)
    if (stored is not None and stored.shape[-1] == jd.size
            and np.array_equal(stored[..., spots], np.asarray(source(jd[spots]), dtype=float))):
        return stored
    samples = np.asarray(source(jd), dtype=float)
    function_store.write_array(path, samples)
    return samples


def _mids(jd_grid, jd_range):
    """The mid-points of the samples ``jd_grid`` inside ``jd_range``, where a spline errs most: a
    track's error is measured there."""
    mids = 0.5 * (jd_grid[:-1] + jd_grid[1:])
    return mids[(mids >= jd_range[0]) & (mids <= jd_range[1])]


def stored_errors(name, decided_by, measure):
    """A track's largest errors (km, m/s), ``measure()``'s, read from the package's cache when
    measured before with the same arrays ``decided_by`` and CasADi version, since evaluating a
    sixty-year track at its twelve thousand mid-points is costly."""
    key = b"\0".join([name.encode(), ca.__version__.encode()]
                      + [np.ascontiguousarray(a, dtype=float).tobytes() for a in decided_by])
    path = function_store.path_of("tracks", name, key, suffix=".npy")
    stored = function_store.read_array(path)
    if stored is not None and stored.shape == (2,):
        return float(stored[0]), float(stored[1])
    errors = np.array(measure(), dtype=float)
    function_store.write_array(path, errors)
    return float(errors[0]), float(errors[1])


def _cartesian(polar):
    """In-plane [x, y, vx, vy] of polar state(s) (4, M)."""
    return np.array(_in_plane(*polar, np.cos, np.sin))


def _in_plane(r, th, vr, vt, cos, sin):
    """[x, y, vx, vy] of a polar state, with numpy's or CasADi's cos and sin."""
    c, s = cos(th), sin(th)
    return [r * c, r * s, vr * c - vt * s, vr * s + vt * c]


def track_of(body, start_jd, stop_jd, step_days=None):
    """The smooth :class:`Track` of ``body``, a planet of :data:`esail_opt.bodies.ephemeris.PLANETS`
    (any case) or a :class:`SmallBody`, over the window [start_jd, stop_jd], Julian dates (TDB), a
    planet's within :data:`esail_opt.bodies.ephemeris.SPAN_JD`.

    ``step_days`` is the samples' spacing, days; by default 1/200 of the osculating period at
    ``start_jd`` (at most 1/16 of the window), halved up to :data:`MAX_HALVINGS` times until the
    error is at most :data:`TARGET_ERROR_KM` and :data:`TARGET_ERROR_M_S`.  Raises InputError for an
    unknown body, a window outside the ephemeris span, stop <= start, or a step not above zero.
    """
    start = check_range("track.start_jd", start_jd)
    stop = check_range("track.stop_jd", stop_jd)
    if not stop > start:
        raise InputError(f"track.stop_jd = {stop_jd!r} must be after track.start_jd = {start_jd!r}")
    if isinstance(body, SmallBody):
        name, source, span = body.name, body.polar_state, None
    else:
        key = ephemeris.planet_key(body, "track.body")
        ephemeris.check_span([start, stop], "track.window")

        def source(jd, key=key):
            return ephemeris.polar_state(key, jd, "track.body")

        name, span = key, ephemeris.SPAN_JD
    if step_days is not None:
        step = check_range("track.step_days", step_days, 0.0, low_open=True, unit="d")
        return Track(name, source, start, stop, step, span)
    step = min(_period_days(source(start)[0]) / SAMPLES_PER_PERIOD, (stop - start) / MIN_STEPS)
    track = Track(name, source, start, stop, step, span)
    for _ in range(MAX_HALVINGS):
        if track.max_error_km <= TARGET_ERROR_KM and track.max_error_m_s <= TARGET_ERROR_M_S:
            break
        step /= 2
        track = Track(name, source, start, stop, step, span)
    return track


def _period_days(polar):
    """Osculating period (days) of a polar state, from vis-viva with mu = 1."""
    r, _th, vr, vt = polar
    a = 1.0 / (2.0 / r - (vr * vr + vt * vt))
    return units.time_to_days(2 * math.pi * a ** 1.5)


class Track3:
    """A body's 3-D state over a window of time as a smooth CasADi function; build one with
    :func:`track3_of` or :func:`track3_on`.  It is the planar :class:`Track` ``planar`` plus the
    height z above the ecliptic and its rate v_z, one cubic B-spline each on the same samples: its
    projection *is* the planar track.  z swings once a revolution with amplitude r sin i, so its
    spline errs by about (5/384) r sin i (2 pi h / P)^4 for a step h and period P, possibly more
    than the plane: the 3-D error is measured, and :func:`track3_on` refines the step.

    Attributes: ``planar``; ``name``, ``jd_range``, ``t_range``, ``step_days``, ``sampled_t_range``
    and ``sampled_jd``, the planar track's; ``max_error_km`` and ``max_error_m_s``, in 3-D;
    ``function``, ``track3(t) -> [x, y, z, vx, vy, vz]`` (6x1, heliocentric, ecliptic of J2000, au
    and au/TU), which holds the end state beyond ``sampled_t_range``; ``cylindrical``,
    ``t -> [r, theta, v_r, v_theta, z, v_z]`` (6x1), from which ``function`` is made.
    """

    def __init__(self, planar, source):
        self.planar = planar
        for key in ("name", "jd_range", "t_range", "step_days", "sampled_t_range", "sampled_jd"):
            setattr(self, key, getattr(planar, key))
        jd = planar.sampled_jd
        states = stored_samples(f"{planar._tag()}_3d", source, jd)
        t_grid = tu_from_jd(jd)
        t = ca.MX.sym("t")
        held = ca.fmin(ca.fmax(t, t_grid[0]), t_grid[-1])  # as in Track: no zeros outside
        z, v_z = (stored_spline(f"{planar._tag()}_{label}", t_grid, states[k])(held)
                  for k, label in ((2, "z"), (5, "v_z")))
        polar = planar.function(t)
        self.cylindrical = ca.Function("track3_cylindrical", [t], [ca.vertcat(polar, z, v_z)],
                                       ["t"], ["cylindrical"])
        x, y, vx, vy = _in_plane(polar[0], polar[1], polar[2], polar[3], ca.cos, ca.sin)
        self.function = ca.Function("track3", [t], [ca.vertcat(x, y, z, vx, vy, v_z)],
                                    ["t"], ["state"])
        self._measure(source, jd, states)

    def state(self, t):
        """The smooth ecliptic state ``[x, y, z, vx, vy, vz]`` (au, au/TU) at canonical time(s) t,
        as :meth:`Track.polar`: shape (6,) or (6, M) for numeric t within :attr:`t_range`
        (InputError otherwise), a 6x1 CasADi expression for symbolic t."""
        if isinstance(t, (ca.SX, ca.MX)):
            return self.function(t)
        times = np.asarray(t, dtype=float)
        self.planar._check_times(times)
        flat = np.atleast_1d(times).ravel()
        values = np.array(self.function.map(flat.size)(flat.reshape(1, -1)))
        return values[:, 0] if times.ndim == 0 else values

    def _measure(self, source, jd_grid, fitted_to):
        mids = _mids(jd_grid, self.jd_range)
        exact = stored_samples(f"{self.planar._tag()}_3d_mids", source, mids)

        def measure():
            diff = (np.array(self.function.map(mids.size)(tu_from_jd(mids).reshape(1, -1)))
                    - exact)
            return (units.length_to_km(np.linalg.norm(diff[:3], axis=0).max()),
                    units.speed_to_m_s(np.linalg.norm(diff[3:], axis=0).max()))

        # The planar track's samples decide its part of this function.
        self.max_error_km, self.max_error_m_s = stored_errors(
            f"{self.planar._tag()}_3d_error",
            (jd_grid, self.planar.samples, fitted_to, mids, exact), measure)

    def __repr__(self):
        return (f"Track3({self.name!r}, {iso_from_jd(self.jd_range[0])} .. "
                f"{iso_from_jd(self.jd_range[1])}, step {self.step_days:.3g} d, "
                f"max error {self.max_error_km:.3g} km, {self.max_error_m_s:.3g} m/s)")


def exact_state_source(body, field="track.body"):
    """``jd -> (6, M)`` exact ecliptic states (au, au/TU) of a planet (DE421) or a SmallBody;
    InputError, naming ``field``, for an unknown planet."""
    if isinstance(body, SmallBody):
        return body.ecliptic_state
    key = ephemeris.planet_key(body, field)
    return lambda jd: ephemeris.ecliptic_state(key, jd, field)


def track3_on(planar, body, refine=False):
    """The :class:`Track3` of ``body`` on the samples of its planar track ``planar``
    (:func:`track_of`'s), so that the two agree in the plane exactly.  With ``refine``, while it
    misses :data:`TARGET_ERROR_KM` or :data:`TARGET_ERROR_M_S`, the step is halved (up to
    :data:`MAX_HALVINGS` times) on a new planar track of its own, which then agrees with
    ``planar`` only to the two tracks' errors."""
    source = exact_state_source(body)
    track = Track3(planar, source)
    for _ in range(MAX_HALVINGS if refine else 0):
        if track.max_error_km <= TARGET_ERROR_KM and track.max_error_m_s <= TARGET_ERROR_M_S:
            break
        planar = track_of(body, *planar.jd_range, planar.step_days / 2)
        track = Track3(planar, source)
    return track


def track3_of(body, start_jd, stop_jd, step_days=None):
    """The smooth :class:`Track3` of a planet or small body over [start_jd, stop_jd]: arguments
    and errors as :func:`track_of`; with the default step refined as :func:`track3_on`, an
    explicit ``step_days`` used as given."""
    return track3_on(track_of(body, start_jd, stop_jd, step_days), body,
                     refine=step_days is None)


__all__ = ["Track", "track_of", "Track3", "track3_of", "track3_on", "exact_state_source"]
