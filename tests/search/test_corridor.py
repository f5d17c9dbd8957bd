"""Corridor search: the least-detectable path, checked against brute force and physics."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from sensorgap.errors import InputError
from sensorgap.models import System
from sensorgap.search.corridor import CERTAIN_COST, corridor_search
from tests.conftest import make_scene


def test_path_is_feasible_and_consistent(system_b: System) -> None:
    scene = make_scene(system_b, "car", "fog_50")
    c = corridor_search(
        scene, -40.0, 6.0, [(-5.625 - 1.875, -3.75), (3.75, 7.5)], speed_rel=8.0, lateral_res=0.5
    )
    assert c.x[0] == pytest.approx(-40.0) and c.x[-1] >= 6.0 - 1e-9
    assert np.all(np.diff(c.x) > 0) and np.all(np.diff(c.t) == pytest.approx(0.05))
    assert np.all(np.abs(np.diff(c.y)) <= 0.5 + 1e-9)  # at most one row per cycle
    on_lane = ((c.y >= -7.5) & (c.y <= -3.75)) | ((c.y >= 3.75) & (c.y <= 7.5))
    assert on_lane.all()
    want = float(np.prod(1.0 - c.pd))  # per-cycle independence
    assert c.p_undetected == pytest.approx(want, rel=1e-9, abs=1e-300)


def test_matches_brute_force_on_a_small_lattice(system_a: System) -> None:
    """Enumerate every lattice path on a tiny problem: Dijkstra finds the best one."""
    scene = make_scene(system_a, "pedestrian", "fog_50")
    c = corridor_search(
        scene, -20.0, -16.0, [(-6.0, -4.0)], speed_rel=20.0, lateral_res=0.5
    )  # 5 columns x 4 rows
    from sensorgap.coverage import evaluate_points

    xs = -20.0 + np.arange(5) * 1.0
    ys = -6.0 + 0.25 + np.arange(4) * 0.5
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    pd = evaluate_points(
        scene, np.column_stack([X.ravel(), Y.ravel(), np.full(X.size, 0.9)])
    ).fused.reshape(5, 4)
    cost = np.where(pd >= 1.0, CERTAIN_COST, -np.log1p(-np.minimum(pd, 1.0)))
    best = math.inf
    for rows in itertools.product(range(4), repeat=5):
        if all(abs(a - b) <= 1 for a, b in itertools.pairwise(rows)):
            best = min(best, sum(cost[i, r] for i, r in enumerate(rows)))
    assert -math.log(max(c.p_undetected, 1e-300)) == pytest.approx(best, rel=1e-9)


def test_rear_blind_side_is_preferred(system_b: System) -> None:
    """Approaching B from behind, the corridor avoids where a rear-facing camera sees best:
    its undetected probability is at least that of driving straight up the lane centre."""
    scene = make_scene(system_b, "car", "rain_25")
    lanes = [(-7.5, -3.75)]
    c = corridor_search(scene, -60.0, 0.0, lanes, speed_rel=10.0, lateral_res=0.25)
    straight = corridor_search(scene, -60.0, 0.0, [(-5.75, -5.5)], speed_rel=10.0, lateral_res=0.25)
    assert c.p_undetected >= straight.p_undetected


@pytest.mark.parametrize(
    ("kw", "pattern"),
    [
        ({"speed_rel": 0.0}, "relative speed must be > 0"),
        ({"x_goal": -50.0}, "must lie ahead of start"),
        ({"lanes": [(1.0, 0.0)]}, "lo < hi"),
    ],
)
def test_bad_input(system_a: System, kw: dict[str, object], pattern: str) -> None:
    args: dict[str, object] = {
        "x_start": -40.0,
        "x_goal": 5.0,
        "lanes": [(-5.0, -2.0)],
        "speed_rel": 5.0,
    }
    args.update(kw)
    with pytest.raises(InputError, match=pattern):
        corridor_search(make_scene(system_a), **args)  # type: ignore[arg-type]


def test_corridor_cli(tmp_path: object, capsys: pytest.CaptureFixture[str]) -> None:
    import json
    from pathlib import Path

    from sensorgap.cli import main

    out = Path(str(tmp_path)) / "c"
    assert (
        main(
            [
                "corridor",
                "--vehicle",
                "system_b",
                "--environment",
                "fog_50",
                "--target",
                "car",
                "--lanes",
                "-7.5:-3.75",
                "--start",
                "-40",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    summary = json.loads((out / "summary.json").read_text())
    assert math.isfinite(summary["log10_p_undetected"]) and summary["log10_p_undetected"] <= 0
    lines = (out / "corridor.csv").read_text().splitlines()
    assert lines[0] == "t,x,y,heading,pd" and len(lines) > 50
    assert (out / "corridor.png").is_file() and (out / "manifest.json").is_file()
    capsys.readouterr()
    assert (
        main(
            [
                "corridor",
                "--vehicle",
                "system_b",
                "--environment",
                "fog_50",
                "--target",
                "car",
                "--lanes",
                "3:1",
                "--out",
                str(tmp_path / "bad"),
            ]
        )
        == 2
    )
    assert "--lanes" in capsys.readouterr().err and not (tmp_path / "bad").exists()


def test_paths_never_enter_the_ego_body(system_a: System) -> None:
    """A band across the ego: the path keeps the target's footprint (car, centred on the
    node) off the body box (System A: x -1.13..4.04 m, half width 0.975 m); a band the body
    fills wholly at some column is refused."""
    scene = make_scene(system_a, "car", "clear")
    body, car = system_a.config.vehicle, scene.target
    c = corridor_search(scene, -30.0, 10.0, [(-3.0, 3.0)], speed_rel=10.0, lateral_res=0.25)
    beside = np.abs(c.y) >= 0.5 * body.width_m + 0.5 * car.width_m
    ahead_or_behind = (c.x <= body.x_rear_m - 0.5 * car.length_m) | (
        c.x >= body.x_front_m + 0.5 * car.length_m
    )
    assert np.all(beside | ahead_or_behind)
    assert not np.all(ahead_or_behind)  # it did pass the body, beside it
    with pytest.raises(InputError, match="runs into the vehicle's own body"):
        corridor_search(scene, -30.0, 10.0, [(-1.0, 1.0)], speed_rel=10.0, lateral_res=0.25)
    # a band ending before the rear bumper is not affected
    corridor_search(scene, -30.0, -4.0, [(-1.0, 1.0)], speed_rel=10.0, lateral_res=0.25)


def test_an_unseen_corridor_is_certainly_undetected_without_a_negative_zero(
    system_a: System,
) -> None:
    """Far behind System A in 50 m fog no sensor sees: P(undetected) is exactly 1 and its
    log10 is 0.0, not -0.0 (hostile round 28: "log10 -0.0" printed and written)."""
    scene = make_scene(system_a, "car", "fog_50")
    c = corridor_search(scene, -1900.0, -1890.0, [(-2.0, 2.0)], speed_rel=10.0, lateral_res=1.0)
    assert np.all(c.pd == 0.0) and c.p_undetected == 1.0
    assert c.log10_p_undetected == 0.0 and math.copysign(1.0, c.log10_p_undetected) == 1.0
