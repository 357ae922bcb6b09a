"""phr.tune: the thesis's optimisation of PHR's alpha and delta on a mesh."""

import phr
import pytest


def test_grid_search_returns_the_best_of_its_evaluations(bunny):
    vertices, indices = bunny
    result = phr.tune(vertices, indices, method="grid", alphas=[0.4, 0.55], deltas=[6, 9])
    evaluations = result["evaluations"]
    assert [(e["alpha"], e["delta"]) for e in evaluations] == [(0.4, 6), (0.4, 9), (0.55, 6), (0.55, 9)]
    best = min(evaluations, key=lambda e: e["value"])
    assert (result["alpha"], result["delta"], result["value"]) == (best["alpha"], best["delta"], best["value"])
    # More refinement costs more build work and gives a cheaper tree.
    by_point = {(e["alpha"], e["delta"]): e for e in evaluations}
    assert by_point[(0.55, 9)]["build_cost"] > by_point[(0.4, 6)]["build_cost"]
    assert by_point[(0.55, 9)]["sah_cost"] < by_point[(0.4, 6)]["sah_cost"]
    assert result["objective"] == "thesis" and result["builds"] == 4 and result["elapsed_ms"] > 0


def test_bayesian_optimisation_stays_in_the_box_and_the_budget(bunny):
    vertices, indices = bunny
    result = phr.tune(vertices, indices, width=128, height=128, method="bo", budget=6, seed=3)
    assert 0.4 <= result["alpha"] <= 0.55 and 6 <= result["delta"] <= 9
    assert len(result["evaluations"]) <= 6 and result["builds"] <= 6
    assert result["value"] == min(e["value"] for e in result["evaluations"])


def test_frame_time_objective_is_in_milliseconds(bunny):
    vertices, indices = bunny
    result = phr.tune(vertices, indices, width=48, height=48, method="grid", objective="frame-time",
                      alphas=[0.45, 0.5], deltas=[6])
    assert result["objective"] == "frame-time"
    assert all(0 < e["value"] < 10_000 for e in result["evaluations"])


def test_bad_arguments_are_refused(bunny):
    vertices, indices = bunny
    with pytest.raises(ValueError, match="method"):
        phr.tune(vertices, indices, method="random")
    with pytest.raises(ValueError, match="objective"):
        phr.tune(vertices, indices, objective="speed")
    with pytest.raises(ValueError, match="budget"):
        phr.tune(vertices, indices, budget=2)
    with pytest.raises(ValueError, match="alphas"):
        phr.tune(vertices, indices, alphas=[])
    with pytest.raises(ValueError, match="no triangles"):
        phr.tune(vertices, indices[:0])
