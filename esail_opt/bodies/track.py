"""A smooth, twice-differentiable form of a body's state over a time window, for the NLP.

The NLP needs a body's polar state as a function of a free time (a departure or arrival
date) that Ipopt can differentiate twice, since it uses exact Hessians.  DE421 is
piecewise Chebyshev with records of 8-32 days whose joints are only approximately smooth,
and the Keplerian solver iterates; neither is a CasADi expression.  A :class:`Track`
samples the exact source on a uniform grid over the window (plus a margin of at least
60 days at each end, where a spline is least accurate and where an NLP iterate may
stray), unwraps the longitude so that it grows continuously past 2 pi, and fits one
cubic B-spline (``casadi.interpolant``, "bspline", not-a-knot) to each of r, theta, v_r
and v_theta.  The spline is C2 and CasADi has its
derivatives in closed form, so first and second derivatives exist for SX and MX inputs.

Why a spline of samples rather than Kepler's equation unrolled in CasADi for small
bodies: one form for every body keeps one contract and one error measurement, and the
fit error is far below the model error of the Keplerian orbit itself.

The default step starts at 1/200 of the body's osculating period at the window's start
(1.8 d for Earth, 3.4 d for Mars, 2.2 d for Bennu) and is halved until the error measured
against the exact source, at the mid-points between samples where a spline's error
peaks, is at most 50 m and 0.1 mm/s.  The error of a cubic spline falls as h^4, so one
halving gains a factor of 16; the measured errors are kept on the track
(:attr:`Track.max_error_km`, :attr:`Track.max_error_m_s`).
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
    """A body's polar state over a window of time as a smooth CasADi function.

    Build one with :func:`track_of`.

    Attributes
    ----------
    name : str
        The body's name.
    jd_range : tuple of float
        (start, stop) Julian dates (TDB) of the window.
    t_range : tuple of float
        The same window in TU since J2000 TDB: the times the track is valid on.
    step_days : float
        Spacing of the samples, days.
    max_error_km, max_error_m_s : float
        The largest in-plane position (km) and velocity (m/s) difference between the
        track and its exact source at the mid-points of the samples inside the window.
    sampled_jd : numpy.ndarray
        The Julian dates (TDB) sampled, uniformly spaced over :attr:`sampled_t_range`.
    samples : numpy.ndarray
        The polar states fitted there, (4, M), theta unwrapped.
    sampled_t_range : tuple of float
        The times sampled, TU: :attr:`t_range` widened by a margin of at least 60 days
        at each end (less where a planet's window meets the ephemeris span).  The spline
        follows the body there too, but its error is only measured on :attr:`t_range`.
    function : casadi.Function
        ``track(t) -> [r, theta, v_r, v_theta]`` (4x1), t in TU since J2000; theta is
        unwrapped, so continuous over the window.  Beyond :attr:`sampled_t_range` it
        holds the end state (zero derivative): bound t to :attr:`t_range` in the NLP.
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
        # CasADi's B-spline is zero outside its knots; holding t at the sampled range
        # keeps a stray NLP iterate on a finite, physical (if frozen) state instead.
        held = ca.fmin(ca.fmax(t, t_grid[0]), t_grid[-1])
        # One spline of four outputs (the sample index slowest): the same fit of each
        # component as four splines would make, at a fraction of the cost to build.
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
        """The smooth polar state ``[r, theta_unwrapped, v_r, v_theta]`` at time(s) t.

        Parameters
        ----------
        t : float, numpy.ndarray of shape (M,), or casadi SX/MX/DM scalar
            Canonical time, TU since J2000 TDB.

        Returns
        -------
        numpy.ndarray of shape (4,) or (4, M) for numeric t (which must lie in
        :attr:`t_range`), a 4x1 CasADi expression for symbolic t.
        """
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
            # Reached by a flight, not by a date the user wrote (those are checked on
            # their own): say which dates would fit.
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
    """CasADi's cubic B-spline interpolant ``name`` through ``values`` on ``grid`` (as
    ``casadi.interpolant(name, "bspline", [grid], values)``), read from the package's
    cache when the same samples were fitted before (:mod:`esail_opt.runtime.function_store`).

    Fitting a track's tens of thousands of samples is most of building it, in every
    process; the stored spline is the one fitted, number for number.  Its file is named
    by the samples' bytes, the name and the CasADi version, so other samples or another
    CasADi fit anew.
    """
    grid = np.ascontiguousarray(grid, dtype=float)
    values = np.ascontiguousarray(values, dtype=float)
    decided_by = b"\0".join([name.encode(), ca.__version__.encode(), grid.tobytes(),
                             values.tobytes()])
    return function_store.kept(function_store.path_of("tracks", name, decided_by),
                               lambda: ca.interpolant(name, "bspline", [grid], values))


#: Dates at which a stored sampling is checked against its source before it is used.
SPOT_CHECKS = 3


def stored_samples(name, source, jd):
    """``source(jd)`` (an array whose last axis runs over ``jd``), read from the package's
    cache when the same dates of ``name`` were sampled before (:mod:`esail_opt.runtime.function_store`).

    Sampling DE421 over a track's sixty years, and again at the mid-points where its
    error is measured, is most of what is left of building a track once its spline is
    stored.  The file is named by ``name`` and the dates' bytes; before it is used the
    source is asked again at :data:`SPOT_CHECKS` of its dates, spread from the first to
    the last, and the stored samples are used only if they are those numbers exactly:
    an ephemeris, a small body's elements or a conversion that changed is sampled
    afresh.
    """
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
    """The mid-points of the samples ``jd_grid`` inside ``jd_range``: where a track's
    error is measured."""
    mids = 0.5 * (jd_grid[:-1] + jd_grid[1:])
    return mids[(mids >= jd_range[0]) & (mids <= jd_range[1])]


def stored_errors(name, decided_by, measure):
    """A track's largest errors (km, m/s) against its source, ``measure()``'s, read from
    the package's cache when the same fit was measured against the same exact samples
    before.

    Evaluating a sixty-year track at its twelve thousand mid-points is most of what is
    left of building it once its spline and samples are stored.  The errors are
    decided by the arrays ``decided_by`` (the samples fitted, the dates measured at and
    the exact states there, which :func:`stored_samples` has checked against the
    source) and by CasADi's version, which fits and evaluates the spline; any other
    array measures afresh.
    """
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
    """The smooth :class:`Track` of a planet or small body over [start_jd, stop_jd].

    Parameters
    ----------
    body : str or SmallBody
        A planet name from :data:`esail_opt.bodies.ephemeris.PLANETS` (any case;
        ``earth`` is the Earth-Moon barycentre) or a :class:`SmallBody`.
    start_jd, stop_jd : float
        The window, Julian dates (TDB), start < stop.  For a planet both must lie within
        :data:`esail_opt.bodies.ephemeris.SPAN_JD`; a small body's two-body orbit has no
        span.
    step_days : float, optional
        Sample spacing, days.  By default it starts at 1/200 of the osculating period at
        ``start_jd`` (at most 1/16 of the window) and is halved, up to 6 times, until the
        measured error is at most :data:`TARGET_ERROR_KM` and :data:`TARGET_ERROR_M_S`.

    Raises
    ------
    InputError
        For an unknown body, a window outside the ephemeris span, stop <= start, or a
        step that is not positive.
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
    """A body's 3-D state over a window of time as a smooth CasADi function.

    Build one with :func:`track3_of` or :func:`track3_on`.  It is a planar
    :class:`Track` (the state projected on the ecliptic, :attr:`planar`) plus the height
    above the ecliptic z and its rate v_z, fitted by the same method on the same samples:
    one cubic B-spline each, held at the sampled ends.  So the projection of this track
    *is* the planar track, spline for spline, and a planar problem and a 3-D one built on
    the same samples see the same body in the plane.  z and v_z are the components the
    projection drops (:func:`esail_opt.bodies.ephemeris.polar_from_ecliptic`).  Their
    samples are not as smooth as the in-plane ones: r and the longitude move slowly and
    steadily, while z swings once a revolution with amplitude r sin i, so its spline
    error is about (5/384) r sin i (2 pi h / P)^4 for a step h and period P (Venus's z
    errs by more than its plane does).  The 3-D error is measured (:attr:`max_error_km`, :attr:`max_error_m_s`)
    and, where the step is chosen here, the step is refined until it meets the targets
    (:func:`track3_on`).

    Attributes
    ----------
    planar : Track
        The projected track whose samples this one shares.
    name, jd_range, t_range, step_days, sampled_t_range, sampled_jd
        As :attr:`planar`'s.
    max_error_km, max_error_m_s : float
        The largest 3-D position (km) and velocity (m/s) difference between the track and
        its exact source at the mid-points of the samples inside the window.
    function : casadi.Function
        ``track3(t) -> [x, y, z, vx, vy, vz]`` (6x1), heliocentric, ecliptic of J2000,
        au and au/TU, t in TU since J2000 TDB.  Beyond :attr:`sampled_t_range` it holds
        the end state: bound t to :attr:`t_range` in the NLP.
    cylindrical : casadi.Function
        ``t -> [r, theta, v_r, v_theta, z, v_z]`` (6x1): the first four are
        ``planar.function``'s outputs (theta unwrapped), the last two the fitted z and
        v_z; :attr:`function` is these turned to Cartesian.
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
        """The smooth ecliptic state ``[x, y, z, vx, vy, vz]`` (au, au/TU) at time(s) t.

        Parameters
        ----------
        t : float, numpy.ndarray of shape (M,), or casadi SX/MX/DM scalar
            Canonical time, TU since J2000 TDB; numeric times must lie in :attr:`t_range`
            (InputError otherwise, as :meth:`Track.polar`).

        Returns
        -------
        numpy.ndarray of shape (6,) or (6, M) for numeric t, a 6x1 CasADi expression for
        symbolic t.
        """
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
    """``jd -> (6, M)`` exact ecliptic states of a planet (DE421) or a SmallBody, au and au/TU.

    Raises InputError, naming ``field``, for an unknown planet.
    """
    if isinstance(body, SmallBody):
        return body.ecliptic_state
    key = ephemeris.planet_key(body, field)
    return lambda jd: ephemeris.ecliptic_state(key, jd, field)


def track3_on(planar, body, refine=False):
    """The :class:`Track3` of ``body`` on the samples of its planar track ``planar``
    (:func:`track_of`'s, for the same body), so that the two agree in the plane exactly.

    With ``refine``, if that 3-D track misses :data:`TARGET_ERROR_KM` or
    :data:`TARGET_ERROR_M_S` (z and v_z may need finer samples than the plane, see
    :class:`Track3`), the step is halved, up to :data:`MAX_HALVINGS` times, on a new
    planar track of its own until it meets them; it then agrees with ``planar`` only to
    the two tracks' errors.
    """
    source = exact_state_source(body)
    track = Track3(planar, source)
    for _ in range(MAX_HALVINGS if refine else 0):
        if track.max_error_km <= TARGET_ERROR_KM and track.max_error_m_s <= TARGET_ERROR_M_S:
            break
        planar = track_of(body, *planar.jd_range, planar.step_days / 2)
        track = Track3(planar, source)
    return track


def track3_of(body, start_jd, stop_jd, step_days=None):
    """The smooth 3-D :class:`Track3` of a planet or small body over [start_jd, stop_jd].

    Arguments and errors as :func:`track_of`, whose planar track it extends.  With the
    default step, the planar track's step is halved further (up to :data:`MAX_HALVINGS`
    times) while the 3-D error exceeds :data:`TARGET_ERROR_KM` or
    :data:`TARGET_ERROR_M_S`; an explicit ``step_days`` is used as given.
    """
    return track3_on(track_of(body, start_jd, stop_jd, step_days), body,
                     refine=step_days is None)


__all__ = ["Track", "track_of", "Track3", "track3_of", "track3_on", "exact_state_source"]
