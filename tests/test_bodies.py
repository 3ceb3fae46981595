"""Layer 2, bodies and time, against sources that share no code with it.

- Dates: ERFA's calendar routines (cal2jd, jd2cal).
- Planets: ERFA's analytical theories epv00 (Earth, VSOP2000-based), moon98 (the Moon) and
  plan94 (Simon et al. 1994), each within the accuracy its documentation states; the
  ecliptic rotation against ERFA's IAU 2006 ecliptic matrix ecm06.
- Small bodies: scipy's DOP853 integrating the two-body problem in Cartesian form, the
  perihelion time and distance JPL Horizons prints beside the elements, and a bracketing
  root finder for Kepler's equation.
- Tracks: the exact sources above at random times, and finite differences of them.
"""

import json
import math

import casadi as ca
import erfa
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from esail_opt.bodies import (
    BENNU,
    CERES,
    J2000_JD,
    PLANETS,
    SPAN_JD,
    SmallBody,
    eccentric_anomaly,
    ecliptic_state,
    iso_from_jd,
    jd_from_iso,
    jd_from_tu,
    lookup,
    polar_state,
    track_of,
    tu_from_jd,
)
from esail_opt.errors import InputError
from esail_opt.physics import constants as units

AU_KM = units.AU / 1e3
ARCSEC = math.pi / 180 / 3600
# 60 dates over 2000-2050, the era the package plans missions in.
DATES_2000_2050 = np.linspace(2451545.0, 2469807.5, 60)
# The obliquity of J2000 written out again here, not taken from the package.
EPS = 84381.448 * ARCSEC


def to_ecliptic(v):
    """Equatorial (J2000) to ecliptic-J2000 axes, written independently of the package."""
    c, s = math.cos(EPS), math.sin(EPS)
    return np.array([v[0], c * v[1] + s * v[2], -s * v[1] + c * v[2]])


def km_of(au):
    return au * AU_KM


def m_s_of(au_per_day):
    return au_per_day * units.AU / units.DAY


# ----------------------------------------------------------------------------- dates

def test_j2000_and_known_dates():
    assert jd_from_iso("2000-01-01T12:00:00") == 2451545.0 == J2000_JD
    assert jd_from_iso("2000-01-01T12:00") == 2451545.0
    assert iso_from_jd(2451545.0) == "2000-01-01T12:00:00"
    assert jd_from_iso("2030-01-01") == 2462502.5
    assert iso_from_jd(2462502.5) == "2030-01-01T00:00:00"
    assert jd_from_iso("2030-01-01 TDB") == 2462502.5
    assert jd_from_iso("2030-01-01T06:00:00.5") == pytest.approx(2462502.75 + 0.5 / 86400, abs=1e-9)
    # A free departure date is written to the millisecond (30 m of a planet's motion).
    assert iso_from_jd(jd_from_iso("2027-10-17T03:46:42.493")) == "2027-10-17T03:46:42.493"
    assert iso_from_jd(2462502.75 + 0.5 / 86400) == "2030-01-01T06:00:00.500"


@settings(max_examples=200, deadline=None)
@given(year=st.integers(1900, 2199), month=st.integers(1, 12), day=st.integers(1, 28),
       hour=st.integers(0, 23), minute=st.integers(0, 59), second=st.integers(0, 59))
def test_dates_against_erfa_and_round_trip(year, month, day, hour, minute, second):
    text = f"{year:04d}-{month:02d}-{day:02d}T{hour:02d}:{minute:02d}:{second:02d}"
    jd = jd_from_iso(text)
    whole, mjd = erfa.cal2jd(year, month, day)
    fraction = erfa.tf2d("+", hour, minute, second)
    # A Julian date near 2.46e6 resolves about 40 microseconds.
    assert jd == pytest.approx(whole + mjd + fraction, abs=1e-9)
    assert iso_from_jd(jd) == text
    y, m, d, f = erfa.jd2cal(jd, 0.0)
    assert (int(y), int(m), int(d)) == (year, month, day)
    assert f * 86400 == pytest.approx(hour * 3600 + minute * 60 + second, abs=1e-4)


def test_canonical_time():
    # TU = sqrt(au^3 / mu_sun), from the SI constants.
    tu_seconds = math.sqrt(1.495978707e11**3 / 1.32712440018e20)
    jd = 2462502.5
    assert tu_from_jd(jd) == pytest.approx((jd - 2451545.0) * 86400 / tu_seconds, rel=1e-14)
    assert jd_from_tu(tu_from_jd(jd)) == pytest.approx(jd, abs=1e-9)
    arr = np.array([2451545.0, 2462502.5])
    np.testing.assert_allclose(jd_from_tu(tu_from_jd(arr)), arr, atol=1e-9)


@pytest.mark.parametrize("bad", ["2030-13-01", "2030-02-30", "2030-1-1", "2030-01-01T25:00",
                                 "2030-01-01T12:60", "2030-01-01T12:00:60", "01/01/2030", "",
                                 "2030-01-01T12:00Z", "2030-01-01T12:00+01:00", 2030])
def test_bad_dates_name_the_field(bad):
    with pytest.raises(InputError, match=r"^departure\.date = .*YYYY-MM-DD"):
        jd_from_iso(bad, field="departure.date")


# ------------------------------------------------------------------------- ephemeris

def test_earth_is_the_earth_moon_barycentre_against_epv00_and_moon98():
    # EMB = Earth + Moon_geocentric / (1 + EMRAT), EMRAT = 81.30057 (DE421's Earth/Moon
    # mass ratio).  Bounds: epv00's stated maximum heliocentric error over 1900-2100 is
    # 11.2 km and 5.0 mm/s; moon98's worst case is 31.7 km and 172 mm/s, divided by
    # 1 + EMRAT = 82.3 (0.39 km, 2.1 mm/s); DE405 (epv00's reference) and DE421 differ by
    # well under 1 km for Earth.
    emrat = 81.30057
    worst_km = worst_mm_s = 0.0
    for jd in DATES_2000_2050:
        helio, _bary = erfa.epv00(jd, 0.0)
        moon = erfa.moon98(jd, 0.0)
        position = to_ecliptic(helio[0] + moon[0] / (1 + emrat))
        velocity = to_ecliptic(helio[1] + moon[1] / (1 + emrat))
        state = ecliptic_state("earth", jd)
        worst_km = max(worst_km, km_of(np.linalg.norm(state[:3] - position)))
        worst_mm_s = max(worst_mm_s, 1e3 * m_s_of(np.linalg.norm(state[3:] / units.TU_DAYS - velocity)))
    assert worst_km < 11.2 + 0.39 + 1.0
    assert worst_mm_s < 5.0 + 2.1


# plan94's maximum differences from DE200 over 1800-2100, as its documentation states:
# longitude L and latitude B in arcsec, radius R in km; and its RMS velocity error against
# DE200 over 1960-2025, m/s (no maximum is stated for the full velocity, only 2.5 m/s for
# Mars's radial rate, so the velocity bound is three times that RMS).
PLAN94 = {"venus": (2, 7, 1, 1100, 0.855), "mars": (4, 26, 1, 9000, 1.98)}


@pytest.mark.parametrize("body", sorted(PLAN94))
def test_planets_against_plan94(body):
    number, l_arcsec, b_arcsec, r_km, v_rms = PLAN94[body]
    for jd in DATES_2000_2050:
        pv = erfa.plan94(2451545.0, jd - 2451545.0, number)
        state = ecliptic_state(body, jd)
        r = np.linalg.norm(pv[0])
        # Angle errors move the planet by r * angle; the radius error adds to that.
        bound = r * (l_arcsec + b_arcsec) * ARCSEC + r_km / AU_KM
        assert np.linalg.norm(state[:3] - to_ecliptic(pv[0])) < bound
        assert m_s_of(np.linalg.norm(state[3:] / units.TU_DAYS - to_ecliptic(pv[1]))) < 3 * v_rms


def test_ecliptic_rotation_against_erfa_ecm06():
    # ecm06 at J2000 is ERFA's ICRS-to-ecliptic matrix (IAU 2006 obliquity 84381.406"
    # and the ICRS frame bias): it differs from the 84381.448" rotation by under 0.07"
    # (3.4e-7 rad), so the two frames agree to 4e-7 r; a wrong axis, sign or angle is off
    # by about 0.4 rad.
    import de421
    from jplephem import Ephemeris

    eph = Ephemeris(de421)
    matrix = erfa.ecm06(2451545.0, 0.0)
    for body, segment in (("mars", "mars"), ("venus", "venus"), ("earth", "earthmoon")):
        for jd in DATES_2000_2050[::6]:
            icrf = (eph.position(segment, jd) - eph.position("sun", jd))[:, 0] / AU_KM
            mine = ecliptic_state(body, jd)[:3]
            assert np.linalg.norm(mine - matrix @ icrf) < 4e-7 * np.linalg.norm(icrf)


def five_point(f, jd, h):
    """Five-point central difference of f(jd) in jd, per day: truncation h^4 f^(5) / 30."""
    return (f(jd - 2 * h) - 8 * f(jd - h) + 8 * f(jd + h) - f(jd + 2 * h)) / (12 * h)


@pytest.mark.parametrize("body", ["earth", "mars", "venus", "mercury"])
def test_velocity_is_the_derivative_of_position(body):
    # Differences of the positions against the velocities: same ephemeris, different code
    # path (jplephem's Chebyshev derivative, the unit conversion of velocities).  A JD near
    # 2.46e6 resolves 4.7e-10 d, which moves a planet by 2.3e-10 d x v; with h = 0.1 d that
    # rounding costs ~3.5e-9 v, and the truncation, ~(n h)^4 / 30 with n up to twice the
    # mean motion at Mercury's perihelion, ~1e-9 v.
    jd = DATES_2000_2050[::7] + 0.123
    numeric = five_point(lambda d: ecliptic_state(body, d)[:3], jd, 0.1)
    velocity = ecliptic_state(body, jd)[3:] / units.TU_DAYS
    assert np.abs(velocity - numeric).max() < 1e-8 * np.linalg.norm(velocity, axis=0).min()


def test_polar_state_is_the_projection():
    jd = np.array([2455000.3, 2460000.7, 2465000.1])
    state = ecliptic_state("Mars", jd)
    polar, z = polar_state("MARS", jd)
    np.testing.assert_allclose(polar[0], np.hypot(state[0], state[1]), rtol=1e-15)
    np.testing.assert_allclose(z, state[2], rtol=1e-15)
    assert np.all(np.abs(polar[1]) <= math.pi)
    np.testing.assert_allclose(np.cos(polar[1]) * polar[0], state[0], rtol=1e-14)
    np.testing.assert_allclose(np.sin(polar[1]) * polar[0], state[1], rtol=1e-14)
    # v_r and v_theta are the rates of the projected r and theta (finite differences).
    # (Five-point differences, h = 0.1 d: see test_velocity_is_the_derivative_of_position.)
    per_tu = units.TU_DAYS
    r_rate = five_point(lambda d: polar_state("mars", d)[0][0], jd, 0.1) * per_tu
    theta_rate = five_point(lambda d: np.unwrap(polar_state("mars", d)[0][1] - polar[1]), jd, 0.1) * per_tu
    np.testing.assert_allclose(polar[2], r_rate, rtol=0, atol=1e-8)
    np.testing.assert_allclose(polar[3], polar[0] * theta_rate, rtol=1e-8)
    single, zs = polar_state("earth", 2462502.5)
    assert single.shape == (4,) and isinstance(zs, float)
    # The ecliptic of J2000 is the EMB's mean orbital plane at J2000; the ecliptic of date
    # tilts from it by 47" a century (IAU precession), and the EMB strays from its mean
    # plane by about 1" (planetary perturbations), so |z| < r (47" |T| + 1"), T in
    # centuries from J2000: 0.5e-5 au at J2000 and 1.2e-4 au in 2050.  A wrong obliquity
    # by 1e-3 rad would put z at 1e-3 au.
    polar_e, z_earth = polar_state("earth", DATES_2000_2050)
    centuries = (DATES_2000_2050 - 2451545.0) / 36525.0
    assert np.all(np.abs(z_earth) < polar_e[0] * (47 * np.abs(centuries) + 1) * ARCSEC)


def test_span_and_its_errors():
    first, last = SPAN_JD
    # DE421 as packaged is documented to cover 1900 through 2050.
    assert first <= jd_from_iso("1900-01-01") and last >= jd_from_iso("2050-12-31")
    ecliptic_state("mars", first)
    ecliptic_state("mars", last)
    with pytest.raises(InputError, match=r"^departure\.date = .* outside the ephemeris span \[1"):
        ecliptic_state("mars", last + 1.0, field="departure")
    with pytest.raises(InputError, match=r"outside the ephemeris span"):
        polar_state("earth", np.array([2460000.5, first - 0.5]))
    with pytest.raises(InputError, match=r"^target = 'pluto' .*mercury, venus, earth, mars, jupiter, saturn"):
        ecliptic_state("pluto", 2460000.5, field="target")
    assert set(PLANETS) == {"mercury", "venus", "earth", "mars", "jupiter", "saturn"}


# ---------------------------------------------------------------------- small bodies

def two_body(_t, y):
    r3 = np.linalg.norm(y[:3]) ** 3
    return np.concatenate([y[3:], -y[:3] / r3])


@pytest.mark.parametrize("body, years", [(BENNU, 1.5), (CERES, 2.0)])
def test_small_body_against_dop853(body, years):
    t_span = units.time_from_years(years)
    start = body.ecliptic_state(body.epoch_jd)
    flown = solve_ivp(two_body, (0.0, t_span), start, method="DOP853", rtol=1e-13,
                      atol=1e-15, dense_output=True)
    times = np.linspace(0.0, t_span, 9)
    mine = body.ecliptic_state(body.epoch_jd + units.time_to_days(times))
    reference = flown.sol(times)
    assert np.abs(mine[:3] - reference[:3]).max() < 1e-9
    assert np.abs(mine[3:] - reference[3:]).max() < 1e-9


@pytest.mark.parametrize("body, tp, qr, period_years, n_deg_day", [
    # JPL Horizons, printed with the elements: TP, QR, PER and N.
    (BENNU, 2455439.14194087, 0.8968944004459729, 1.19548, 0.824461327),
    (CERES, 2458240.1791309435, 2.556401146697176, 4.60851, 0.213870839),
])
def test_small_body_against_horizons_perihelion(body, tp, qr, period_years, n_deg_day):
    state = body.ecliptic_state(tp)
    # At perihelion r = q and r.v = 0 (v has no radial part); a slip in the mean anomaly,
    # the mean motion or the epoch moves the body off perihelion by n dt.
    assert np.linalg.norm(state[:3]) == pytest.approx(qr, abs=1e-10)
    assert abs(state[:3] @ state[3:]) < 1e-9
    assert body.period_days / 365.25 == pytest.approx(period_years, rel=5e-6)  # 6 digits printed
    # Horizons' N and sqrt(mu_sun / a^3) agree to 3e-8 (the GM it uses is not printed).
    assert math.degrees(body.mean_motion) / units.TU_DAYS == pytest.approx(n_deg_day, rel=1e-7)


@pytest.mark.parametrize("body", [BENNU, CERES])
def test_small_body_period_returns(body):
    start = body.ecliptic_state(body.epoch_jd)
    again = body.ecliptic_state(body.epoch_jd + 3 * body.period_days)
    np.testing.assert_allclose(again, start, rtol=0, atol=1e-11)


@pytest.mark.parametrize("e", [0.0, 0.2, 0.9, 0.99])
def test_kepler_equation(e):
    m = np.concatenate([np.linspace(-3 * math.pi, 3 * math.pi, 241), [0.0, 1e-9, math.pi, -math.pi]])
    big_e = eccentric_anomaly(m, e)
    assert np.abs(big_e - e * np.sin(big_e) - m).max() < 1e-14
    if e == 0.0:
        np.testing.assert_array_equal(big_e, m)
    for mi, ei in zip(m[::20], big_e[::20]):
        root = brentq(lambda x, mi=mi: x - e * math.sin(x) - mi, mi - 1.0, mi + 1.0, xtol=1e-15)
        assert ei == pytest.approx(root, abs=1e-13)


@pytest.mark.parametrize("changes, field", [
    ({"e": 1.0}, "body.e"), ({"e": -0.1}, "body.e"), ({"a_au": 0.0}, "body.a_au"),
    ({"a_au": float("nan")}, "body.a_au"), ({"inclination_deg": 120.0}, "body.inclination_deg"),
    ({"node_deg": 400.0}, "body.node_deg"), ({"mean_anomaly_deg": "x"}, "body.mean_anomaly_deg"),
    ({"epoch": "2020-02-31"}, "body.epoch"), ({"name": ""}, "body.name"),
    ({"argument_of_perihelion_deg": 400.0}, "body.argument_of_perihelion_deg"),
    ({"argument_of_perihelion_deg": None, "perihelion_deg": 800.0}, "body.perihelion_deg"),
])
def test_small_body_checks_its_fields(changes, field):
    fields = dict(name="test", a_au=1.5, e=0.1, inclination_deg=2.0, node_deg=10.0,
                  argument_of_perihelion_deg=40.0, mean_anomaly_deg=20.0, epoch="2030-01-01",
                  source="test")
    fields.update(changes)
    with pytest.raises(InputError, match="^" + field.replace(".", r"\.") + " = "):
        SmallBody(**fields)


SMALL = dict(name="test", a_au=1.5, e=0.1, inclination_deg=2.0, node_deg=310.0,
             mean_anomaly_deg=20.0, epoch="2030-01-01")


@pytest.mark.parametrize("given", [dict(argument_of_perihelion_deg=100.0, perihelion_deg=50.0),
                                   dict()], ids=["both", "neither"])
def test_small_body_takes_exactly_one_perihelion_angle(given):
    """Both angles lie in the same range, so a catalogue's w pasted as the longitude
    is not caught by a range: both or neither is refused in one line that names each
    field and says what it is."""
    with pytest.raises(InputError) as caught:
        SmallBody(**SMALL, **given)
    message = str(caught.value)
    assert "\n" not in message
    assert message.startswith(
        f"body.argument_of_perihelion_deg = {given.get('argument_of_perihelion_deg')!r} and "
        f"body.perihelion_deg = {given.get('perihelion_deg')!r}: give exactly one")
    for words in ("argument_of_perihelion_deg (omega, measured from the ascending node",
                  "small-body database lists it as w", "in [-360, 360] deg",
                  "perihelion_deg (the longitude of perihelion, node + omega)",
                  "in [-720, 720] deg"):
        assert words in message
    # The angles after the node are named: the old positional form, whose sixth number
    # meant the longitude, is refused rather than read as either angle.
    with pytest.raises(TypeError):
        SmallBody("test", 1.5, 0.1, 2.0, 310.0, 50.0, 20.0, "2030-01-01")


@pytest.mark.parametrize("argument", [100.0, 0.0, 359.5, -30.0])
def test_small_body_by_argument_or_by_longitude_is_one_orbit(argument):
    """omega and varpi = node + omega give one body: the same state, and each angle
    read back as the other implies (varpi wrapped into [0, 360))."""
    by_argument = SmallBody(**SMALL, argument_of_perihelion_deg=argument)
    longitude = SMALL["node_deg"] + argument  # 410, 310, 669.5, 280 deg: unwrapped
    by_longitude = SmallBody(**SMALL, perihelion_deg=longitude)
    assert by_argument.perihelion_deg == pytest.approx(longitude % 360.0, abs=1e-12)
    assert 0.0 <= by_argument.perihelion_deg < 360.0
    assert math.remainder(by_longitude.argument_of_perihelion_deg - argument, 360.0) \
        == pytest.approx(0.0, abs=1e-12)
    jd = jd_from_iso("2033-07-04") + np.array([0.0, 123.4, 987.6])
    np.testing.assert_allclose(by_longitude.ecliptic_state(jd), by_argument.ecliptic_state(jd),
                               rtol=0, atol=1e-12)
    # The catalogue's w pasted as the longitude is another orbit: an au away, not 1e-12.
    misread = SmallBody(**SMALL, perihelion_deg=argument)
    miss = np.linalg.norm(misread.ecliptic_state(jd)[:3] - by_argument.ecliptic_state(jd)[:3],
                          axis=0)
    assert miss.min() > 0.5


@pytest.mark.parametrize("body", [BENNU, CERES])
def test_shipped_small_bodies_are_written_with_the_argument_of_perihelion(body):
    """A solution file holds the body by its fields: the argument, not the longitude.
    A file written before the argument existed (its body with ``perihelion_deg``) still
    gives the same body back."""
    written = lookup.describe(body)
    assert "argument_of_perihelion_deg" in written and "perihelion_deg" not in written
    assert lookup.resolve(json.loads(json.dumps(written))) == body
    older = dict(written, perihelion_deg=body.node_deg + written.pop("argument_of_perihelion_deg"))
    again = lookup.resolve(older)
    jd = body.epoch_jd + np.array([0.0, 500.0])
    np.testing.assert_allclose(again.ecliptic_state(jd), body.ecliptic_state(jd), rtol=0,
                               atol=1e-12)


# ---------------------------------------------------------------------------- tracks

WINDOW = (jd_from_iso("2030-01-01"), jd_from_iso("2036-01-01"))  # six years


def exact_source(body):
    if isinstance(body, SmallBody):
        return body.polar_state
    return lambda jd: polar_state(body, jd)


def in_plane(polar):
    r, th, vr, vt = polar
    c, s = np.cos(th), np.sin(th)
    return np.array([r * c, r * s, vr * c - vt * s, vr * s + vt * c])


@pytest.mark.parametrize("body", ["earth", "mars", "venus", BENNU, CERES],
                         ids=["earth", "mars", "venus", "bennu", "ceres"])
def test_track_against_exact_source(body):
    track = track_of(body, *WINDOW)
    rng = np.random.default_rng(7)
    jd = rng.uniform(*WINDOW, 400)
    exact, _ = exact_source(body)(jd)
    smooth = track.polar(tu_from_jd(jd))
    diff = in_plane(smooth) - in_plane(exact)
    assert km_of(np.hypot(diff[0], diff[1]).max()) < 1.0
    assert units.speed_to_m_s(np.hypot(diff[2], diff[3]).max()) < 1e-3
    assert track.max_error_km < 1.0 and track.max_error_m_s < 1e-3
    # theta is unwrapped: continuous, growing (prograde), and equal to the exact
    # longitude modulo 2 pi.
    ordered = track.polar(np.linspace(*track.t_range, 2000))[1]
    assert np.all(np.diff(ordered) > 0)
    turns = (smooth[1] - exact[1]) / (2 * math.pi)
    np.testing.assert_allclose(turns, np.round(turns), atol=1e-6)
    assert track.t_range == pytest.approx((tu_from_jd(WINDOW[0]), tu_from_jd(WINDOW[1])))


def test_track_derivatives_and_hessian():
    track = track_of("mars", *WINDOW)
    t = ca.MX.sym("t")
    x = track.function(t)
    rate = ca.Function("rate", [t], [ca.jacobian(x, t)])
    h_days = 0.05
    for jd in np.random.default_rng(3).uniform(WINDOW[0] + 1, WINDOW[1] - 1, 20):
        ahead, _ = polar_state("mars", jd + h_days)
        behind, _ = polar_state("mars", jd - h_days)
        numeric = (ahead - behind) / (2 * units.time_from_days(h_days))
        numeric[1] = np.unwrap([behind[1], ahead[1]])[1] - behind[1]
        numeric[1] /= 2 * units.time_from_days(h_days)
        # Central differences err by h^2 f'''/6 (~1e-9 here); the spline's derivative
        # errs by about h_s^3 f'''' (h_s = 1.7 d): 1e-7 in these units (au, rad, TU) is
        # 1e-7 rad/TU on the longitude rate and 3 mm/s on dr/dt.
        np.testing.assert_allclose(np.array(rate(tu_from_jd(jd))).ravel(), numeric, atol=1e-7)
    # Second derivatives exist symbolically (Ipopt's exact Hessian) and match differences
    # of the first.
    r, th = x[0], x[1]
    expression = r * ca.cos(th) + 0.5 * r**2 * ca.sin(th)
    hess, grad = ca.hessian(expression, t)
    both = ca.Function("both", [t], [grad, hess])
    t0 = float(np.mean(track.t_range))
    step = 1e-4
    g_plus, _ = both(t0 + step)
    g_minus, _ = both(t0 - step)
    _, h0 = both(t0)
    assert float(h0) == pytest.approx((float(g_plus) - float(g_minus)) / (2 * step), rel=1e-6)
    assert abs(float(h0)) > 0.1  # a real curvature, not a zero from a missing derivative
    # SX input gives a CasADi expression too.
    assert track.polar(ca.SX.sym("s")).shape == (4, 1)


def test_track_errors():
    first, last = SPAN_JD
    with pytest.raises(InputError, match="outside the ephemeris span"):
        track_of("earth", first - 10, first + 1000)
    with pytest.raises(InputError, match="outside the ephemeris span"):
        track_of("mars", last - 100, last + 100)
    with pytest.raises(InputError, match="^track.body = 'ceres' is not a known planet"):
        track_of("ceres", *WINDOW)
    with pytest.raises(InputError, match="^track.stop_jd"):
        track_of("earth", WINDOW[1], WINDOW[0])
    with pytest.raises(InputError, match="^track.step_days"):
        track_of("earth", *WINDOW, step_days=0.0)
    track = track_of("venus", WINDOW[0], WINDOW[0] + 100)
    beyond = iso_from_jd(WINDOW[0] + 200)
    with pytest.raises(InputError, match=f"^venus is needed on {beyond} TDB, outside the "
                                         "dates it is known at .*arrival_window"):
        track.polar(tu_from_jd(WINDOW[0] + 200))
    # Symbolic or function calls a little outside the window (an NLP iterate) still follow
    # the body; far outside they hold the sampled end state rather than CasADi's zeros.
    for days in (-30.0, 30.0):
        jd = (WINDOW[0] if days < 0 else WINDOW[0] + 100) + days
        near = np.array(track.function(tu_from_jd(jd))).ravel()
        exact, _ = polar_state("venus", jd)
        diff = in_plane(near) - in_plane(exact)
        assert km_of(math.hypot(diff[0], diff[1])) < 1.0
    far = np.array(track.function(tu_from_jd(WINDOW[0] - 1000))).ravel()
    end = np.array(track.function(track.sampled_t_range[0])).ravel()
    np.testing.assert_array_equal(far, end)
    assert far[0] == pytest.approx(0.72, abs=0.01)
    # A small body's two-body orbit has no span: a window after DE421 is fine.
    late = track_of(BENNU, last + 10, last + 400)
    assert late.max_error_km < 1.0
