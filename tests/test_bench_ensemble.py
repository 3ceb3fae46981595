"""The ensemble bench: robust's closed-form flights against CVODES, flight by flight, and
the record it writes."""

import json

import numpy as np
import pytest

from conftest import REPO
from esail_opt.optimisation.robustness import AGREEMENT
from esail_opt.bench import ensemble

SOLUTION = REPO / "results" / "earth_mars_min_ac"
FLIGHTS = 50


@pytest.fixture(scope="module")
def mission():
    return ensemble.load(SOLUTION)[1]


def test_closed_form_departures_from_the_nominal_are_cvodes_departures(mission):
    """Fifty flights of the Earth-Mars rendezvous under the default wind, on the closed
    form and on CVODES at 1e-12.  The closed form's model error on this transfer is a
    few thousand km and nearly the same in every flight, so the bench compares the
    departures from the nominal flight, as robust uses them: each flight's closed-form
    departure from the nominal closed form must be its CVODES departure from the nominal
    CVODES flight to within robust's agreement fraction of that departure (the bound its
    CVODES checks apply)."""
    acs = ensemble.flights(mission, FLIGHTS)
    closed = ensemble.closed_form(mission.plan, acs, repeats=1)
    flown = ensemble.cvodes(mission.plan, acs)
    assert closed["arrivals"].shape == flown["arrivals"].shape == (6, FLIGHTS)
    accuracy = ensemble.closed_form_accuracy(mission, closed["arrivals"], flown["arrivals"])
    assert accuracy["corrected_over_deviation"]["max"] <= AGREEMENT
    # The correction is what makes the closed form usable: without it the arrival is
    # off by the model error, which the correction takes out.
    assert accuracy["corrected_error_km"]["median"] < accuracy["error_km"]["median"]


def test_the_record_holds_each_method_and_heyoka_agrees_with_cvodes(tmp_path, monkeypatch,
                                                                     capsys):
    """A run of 50 flights writes ensemble.json with each method's time per flight,
    errors and ratios.  With heyoka (one tolerance and one batch size, to stay short),
    its flight of the Cartesian equations ends within 1 m of CVODES's turning-plane
    flight at the verifier's tolerance (CVODES there is within 0.25 m of DOP853 on
    these schedules, simulate.VERIFY_TOLERANCE), which checks the thrust written in
    heyoka's expressions; without it the record says it was skipped."""
    monkeypatch.setattr(ensemble, "HEYOKA_TOLERANCES", (1e-12,))
    monkeypatch.setattr(ensemble, "HEYOKA_LANES", (1,))
    path = ensemble.run(tmp_path, 1, flights=FLIGHTS, solution=SOLUTION)
    assert path == tmp_path / "ensemble.json"
    record = json.loads(path.read_text())
    assert record["case"]["flights"] == FLIGHTS
    for key in ("seconds_per_flight", "first_call_seconds", "error_km", "corrected_error_km",
                "deviation_km", "corrected_over_deviation"):
        assert key in record["closed_form"]
    assert record["cvodes"]["flights_timed"] == ensemble.CVODES_FLIGHTS
    assert record["cvodes"]["tolerance"] == 1e-12
    assert record["ratios"]["cvodes_over_closed_form"] > 0
    assert [row["method"] for row in record["per_flight"]][:3] == [
        "closed form", "closed form, corrected as robust", "CVODES 1e-12"]
    assert all(row["us_per_flight"] > 0 for row in record["per_flight"])
    check = record["check_flight"]
    # CVODES at 1e-12, the reference of every error, is itself off by no more than the
    # closed form's corrected error.
    corrected = record["closed_form"]["corrected_error_km"]["max"]
    assert check["cvodes_1e-12"]["position_km"] < corrected
    printed = capsys.readouterr().out
    assert "us" in printed and "km" in printed
    if "skipped" in record["heyoka"]:
        assert "heyoka skipped" in printed
        assert record["ratios"]["heyoka_tight_over_closed_form"] is None
        return
    (point,) = record["heyoka"]["points"]
    assert point["tolerance"] == 1e-12 and np.isfinite(point["error_km"]["max"])
    assert record["ratios"]["heyoka_tight_over_closed_form"] > 0
    assert check[f"heyoka_{ensemble.CHECK_TOLERANCE:g}"]["position_km"] < 1e-3
