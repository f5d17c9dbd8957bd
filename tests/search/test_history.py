"""The detection history starts at t = 0: a slower car ahead must start beyond every
confirming sensor's reach (``search.possible.in_reach``; session 17's review found rows
whose collision probability the cut-off history overstated: here 1.00 instead of 0.03)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from sensorgap.config import load_environments
from sensorgap.config.presets import templates_dir
from sensorgap.models import load_system
from sensorgap.scenarios import load_family
from sensorgap.scenarios.kinds import SlowAhead
from sensorgap.search.evaluate import Evaluator
from sensorgap.search.possible import in_reach
from sensorgap.search.problem import Candidate, SearchProblem
from sensorgap.search.run import run_search


def test_in_reach_measures_to_the_nearest_point_of_the_body() -> None:
    """Horizontal distance from a sensor to the target's box, by hand (tolerance 1e-9 m):
    a 4.5 x 1.8 m car 100 m ahead seen from (2, 0): 100 - 2.25 - 2 = 95.75 m; turned
    across (90 deg): 100 - 0.9 - 2 = 97.1 m; 100 m ahead and 30 m left of a sensor at
    (2, 0), heading along: hypot(100 - 2.25 - 2, 30 - 0.9) m. The sensor it is deepest
    within counts; beyond every reach: -1 and inf."""
    x = np.array([100.0, 100.0, 100.0, 100.0])
    y = np.array([0.0, 0.0, 30.0, 0.0])
    psi = np.array([0.0, 0.5 * math.pi, 0.0, 0.0])
    mounts = [(2.0, 0.0, 150.0), (2.0, 0.0, 250.0)]
    which, dist = in_reach(x, y, psi, 4.5, 1.8, mounts)
    assert which.tolist() == [1, 1, 1, 1]
    want = [95.75, 97.1, math.hypot(95.75, 29.1), 95.75]
    assert dist == pytest.approx(want, abs=1e-9)
    which, dist = in_reach(x, y, psi, 4.5, 1.8, [(2.0, 0.0, 95.7), (2.0, 0.0, 97.0)])
    assert which.tolist() == [1, -1, -1, 1]
    assert dist[1] == math.inf and dist[0] == pytest.approx(95.75, abs=1e-9)


def _problem() -> SearchProblem:
    return SearchProblem(
        load_family("slow_ahead_curve"),
        {"snow": load_environments()["snow"]},
        Evaluator(load_system("system_b"), "exact"),
    )


#: System B on the motorway curve in snow: the ego at 25 m/s, the car at 5 m/s 100 m ahead
#: of it at s = 734.79 m (session 17's example was a glare row that the veil model of
#: 2026-11-27 no longer makes critical).
EGO_S0, EGO_V, GAP0, CAR_V = 734.79, 25.0, 100.0, 5.0


def _started_earlier(dt: float) -> dict[str, float]:
    """The same encounter started ``dt`` s earlier: both further back on their paths at
    their constant speeds (so the same trajectories after)."""
    return {
        "ego_s0_m": EGO_S0 - EGO_V * dt,
        "ego_speed_m_s": EGO_V,
        "gap0_m": GAP0 + (EGO_V - CAR_V) * dt,
        "target_speed_m_s": CAR_V,
    }


def test_a_start_within_reach_overstates_and_is_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    """Started 100 m apart in snow (within cam_narrow's 250 m), the encounter's
    P(collision) is 1.00; started 8.3 s earlier (266 m apart, beyond every confirming
    sensor's reach) it is 0.031, and started 9.3 s earlier the same to 1e-12 (nothing
    before the reach adds a chance to detect). The rule refuses the first with a note
    naming the sensor and the distance (95.9 m by the geometry: 100 m less the car's half
    length and the camera's 1.95 m, along the curve's chord) and uses the others."""
    prob = _problem()

    def run(dt: float) -> tuple[bool, str, float]:
        r = prob.evaluate(Candidate("slow_ahead_curve", "snow", None, _started_earlier(dt)))
        return r.feasible, r.note, r.metrics.get("collision_probability", -1.0)

    feasible, note, _ = run(0.0)
    assert not feasible
    assert note.startswith("starts within reach: the car is 95.9 m from cam_narrow (reach 250 m)")
    far, farther = run(8.3), run(9.3)
    assert far[0] and farther[0]
    assert far[2] == pytest.approx(0.03095, abs=1e-5)
    assert abs(far[2] - farther[2]) < 1e-12
    monkeypatch.setattr(SlowAhead, "start_out_of_reach", False)
    cut_off = run(0.0)
    assert cut_off[0] and cut_off[2] > 0.999  # what the cut-off history claimed


def test_search_stores_starts_within_reach_as_infeasible(tmp_path: Path) -> None:
    """A search over gaps that begin inside the reach: those candidates are infeasible,
    counted under their own kind in summary.json, and every ranked row starts beyond the
    reach of every confirming sensor (System B's cameras: 250 m)."""
    fam = tmp_path / "near_start.toml"
    text = (templates_dir() / "scenarios" / "slow_ahead_curve.toml").read_text(encoding="utf-8")
    fam.write_text(text.replace("gap0_m = [250.0, 420.0]", "gap0_m = [150.0, 420.0]"))
    out = tmp_path / "run"
    res = run_search(
        "system_b", [str(fam)], ["snow"], 200, 2, 10, out, strategy="lhs", progress=False
    )
    summary = json.loads((out / "summary.json").read_text())
    kinds = [k for k in summary["infeasible_reasons"] if k.startswith("starts within reach")]
    assert kinds and summary["infeasible_reasons"][kinds[0]] > 0
    assert res.ranking
    assert all(r["p_gap0_m"] > 250.0 for r in res.ranking)


def test_a_radar_confirming_only_moving_targets_counts_only_for_a_moving_car(
    tmp_path: Path,
) -> None:
    """Hostile round fifteen: System B's radar confirms a target only while it moves at 5
    m/s or more (reactions.toml). With its reach raised from 160 to 1,000 m, a stopped car
    300 m ahead (beyond the cameras' 250 m) is usable: the radar can never confirm it; the
    same car at 10 m/s is within the radar's reach and refused, named by it."""
    text = (templates_dir() / "vehicles" / "system_b.toml").read_text(encoding="utf-8")
    old = 'id = "radar_front"'
    head, tail = text.split(old)
    assert "max_range_m = 160.0" in tail
    vehicle = tmp_path / "long_radar.toml"
    vehicle.write_text(head + old + tail.replace("max_range_m = 160.0", "max_range_m = 1000.0", 1))
    prob = SearchProblem(
        load_family("slow_ahead_curve"),
        {"clear": load_environments()["clear"]},
        Evaluator(load_system(str(vehicle)), "exact"),
    )
    params = {"ego_s0_m": 300.0, "ego_speed_m_s": 30.0, "gap0_m": 300.0}
    stopped = prob.evaluate(
        Candidate("slow_ahead_curve", "clear", None, {**params, "target_speed_m_s": 0.0})
    )
    assert stopped.feasible, stopped.note
    moving = prob.evaluate(
        Candidate("slow_ahead_curve", "clear", None, {**params, "target_speed_m_s": 10.0})
    )
    assert not moving.feasible
    assert moving.note.startswith("starts within reach: the car is ")
    assert "from radar_front (reach 1000 m)" in moving.note


def test_the_no_feasible_note_lists_the_most_frequent_reason_first() -> None:
    """Hostile round fifteen: the printed line listed the kinds by count, the report
    (from summary.json, whose keys are sorted) alphabetically; both by count now, the
    rest ("other") last."""
    from sensorgap.search.possible import no_feasible_note

    note = no_feasible_note(100, {"a rare kind": 5, "other": 40, "starts within reach": 55})
    assert "(55 starts within reach; 5 a rare kind; 40 other)" in note
