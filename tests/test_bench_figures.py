"""``esail-opt-bench figures``: what it writes, and that both ways draw the same pixels."""

import json

import pytest

from esail_opt.bench import figures


@pytest.mark.slow
def test_the_figures_bench_records_every_way_and_the_same_pixels(tmp_path):
    path = figures.run(tmp_path, repeats=1)
    data = json.loads(path.read_text())
    assert path.name == "figures.json" and data["runs"] == 1
    assert data["case"] == {"problem": "earth_mars_min_time", "polished": True,
                            "figures": ["timeline.png", "trajectory.png"]}
    assert (len(data["drafted_worker_runs_seconds"]) == len(data["worker_runs_seconds"])
            == len(data["in_process_runs_seconds"]) == 1)
    assert data["ratio_in_process_over_worker"] == (data["in_process_seconds"]
                                                    / data["worker_seconds"])
    assert data["ratio_in_process_over_drafted_worker"] == (
        data["in_process_seconds"] / data["drafted_worker_seconds"])
    assert data["same_pixels"] is True
