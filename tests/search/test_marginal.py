"""Marginal scenarios (search/ranking.classify, problem.search_objective): a collision that
perfect perception avoids by less than one confirmation window is not a sensor weakness."""

from __future__ import annotations

import numpy as np

from sensorgap.search.metrics import metric_names
from sensorgap.search.problem import (
    MIN_PERFECT_MARGIN_S,
    OBJECTIVE_UNAVOIDABLE,
    Candidate,
    Result,
    search_objective,
)
from sensorgap.search.ranking import classify


def _result(p: float, perfect: float, margin: float | None) -> Result:
    metrics = {name: 0.0 for name in metric_names()}
    metrics.update(collision_probability=p, collision_perfect=perfect)
    if margin is None:
        del metrics["perfect_margin_s"]
    else:
        metrics["perfect_margin_s"] = margin
    return Result(Candidate("f", "clear", None, {}), metrics, True)


def test_classes_by_the_reference_margin() -> None:
    """0.25 s is one confirmation window of the presets (5 cycles at 20 Hz)."""
    assert MIN_PERFECT_MARGIN_S == 0.25
    assert classify(_result(1.0, 0.0, 0.10)) == "marginal"
    assert classify(_result(1.0, 0.0, 0.25)) == "sensor-critical"
    assert classify(_result(1.0, 0.0, 2.0)) == "sensor-critical"
    assert classify(_result(1.0, 0.0, float("nan"))) == "marginal"
    assert classify(_result(1.0, 1.0, float("nan"))) == "unavoidable"
    assert classify(_result(0.0, 0.0, 0.05)) == "not critical"
    assert classify(_result(0.5, 0.0, None)) == "sensor-critical"  # metric absent


def test_the_search_steers_away_from_marginal_encounters() -> None:
    obj = search_objective(
        np.array([-1.0, -1.0, -1.0]),
        np.zeros(3),
        np.array([0.9, 0.9, 0.9]),
        np.array([0.0, 0.0, 1.0]),
        np.array([0.1, 0.5, np.nan]),
    )
    assert obj[0] == OBJECTIVE_UNAVOIDABLE and obj[2] == OBJECTIVE_UNAVOIDABLE
    assert obj[1] == np.log10(0.9)
