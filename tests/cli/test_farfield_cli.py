"""Far field on the committed motorway: Table IV levels, files, bad road input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sensorgap.analysis.farfield import EgoPose, farfield, level_lengths, path_ahead
from sensorgap.analysis.paper import (
    FarFieldSetup,
    ego_pose,
    paper_system,
    run_farfield,
    target_path,
)
from sensorgap.cli import main
from sensorgap.config.presets import resolve_road
from sensorgap.errors import InputError
from sensorgap.models import System, load_system
from sensorgap.roads import read_opendrive
from tests.conftest import make_scene


def test_level_lengths_by_hand() -> None:
    pd = np.array([1.0, 1.0, 0.9, 0.6, 0.3, 0.0, 0.0])
    ds = np.full(7, 0.5)
    assert level_lengths(pd, ds) == {
        "pd=1.0": 1.0,
        "pd>=0.8": 1.5,
        "pd>=0.5": 2.0,
        "pd>0": 2.5,
        "pd=0": 1.0,
    }


def test_path_ahead_starts_at_front_bumper() -> None:
    x = np.linspace(-50.0, 500.0, 1101)
    path = np.column_stack([x, np.full_like(x, -3.75)])
    pose = EgoPose(10.0, 0.0, 0.0)
    world, s, ds = path_ahead(path, pose, x_front=4.0, length_m=100.0, step_m=0.5)
    assert world[0, 0] == pytest.approx(14.25)  # 10 + 4 + half a step
    assert ds.sum() == pytest.approx(100.0) and s[-1] == pytest.approx(99.75)
    with pytest.raises(InputError, match="only .* m of the target lane"):
        path_ahead(path, pose, x_front=4.0, length_m=1000.0, step_m=0.5)


def test_farfield_straight_road_by_geometry(system_a: System) -> None:
    """On a straight road, a target far beyond every sensor's range has Pd = 0 exactly."""
    x = np.linspace(0.0, 2000.0, 4001)
    path = np.column_stack([x, np.full_like(x, -3.75)])
    ff = farfield(make_scene(system_a), path, EgoPose(0.0, 0.0, 0.0), length_m=600.0)
    beyond = ff.vehicle[:, 0] > 260.0  # longest range: 250 m radar
    assert np.all(ff.pd[beyond] == 0.0)
    assert ff.levels_m["pd=0"] >= 600.0 - 262.0
    assert sum(ff.levels_m[k] for k in ("pd>0", "pd=0")) == pytest.approx(600.0)


def test_farfield_bodies_on_a_straight_road(system_a: System) -> None:
    """Bodies along a straight lane: heading along it (relative heading 0), Pd equal to
    the body model at those poses; beyond every sensor's range plus the body's half
    length, Pd = 0 exactly; in the near range (ahead, within the front cameras' and
    radar's view) the body is seen with Pd 1 like the point."""
    from sensorgap.coverage.body import body_per_sensor_pd

    x = np.linspace(0.0, 2000.0, 4001)
    path = np.column_stack([x, np.full_like(x, -3.75)])
    scene = make_scene(system_a)
    ff = farfield(scene, path, EgoPose(0.0, 0.0, 0.0), length_m=600.0, bodies=True)
    pts = farfield(scene, path, EgoPose(0.0, 0.0, 0.0), length_m=600.0)
    np.testing.assert_allclose(ff.vehicle, pts.vehicle)
    pd, _ = body_per_sensor_pd(scene, ff.vehicle[:, 0], ff.vehicle[:, 1], np.zeros(len(ff.s)))
    np.testing.assert_allclose(ff.pd, 1.0 - np.prod(1.0 - pd, axis=0), atol=1e-12)
    assert np.all(ff.pd[ff.vehicle[:, 0] > 260.0 + 2.5] == 0.0)
    near = (ff.vehicle[:, 0] > 20.0) & (ff.vehicle[:, 0] < 60.0)
    assert np.all(ff.pd[near] == pytest.approx(1.0)) and np.all(pts.pd[near] == pytest.approx(1.0))


def test_motorway_setup_matches_the_paper_geometry() -> None:
    net = read_opendrive(resolve_road("motorway_r500"))
    setup = FarFieldSetup()
    path = target_path(net, setup)
    assert len(path) > 100
    b = paper_system(load_system("system_b"), "glare")
    _, ff = run_farfield(b, "glare_front_right", setup, net)
    assert ff.ds.sum() == pytest.approx(303.0)
    # B under the paper's glare: cameras blind, radar only, never certain
    assert ff.levels_m["pd=1.0"] == 0.0


def test_farfield_cli_files(tmp_path: Path) -> None:
    out = tmp_path / "ff"
    assert (
        main(["farfield", "--vehicle", "system_a", "--environment", "clear", "--out", str(out)])
        == 0
    )
    for name in ("farfield.csv", "levels.csv", "farfield.png", "summary.json"):
        assert (out / name).is_file()
    levels = (out / "levels.csv").read_text().splitlines()
    assert levels[0] == "level,metres" and len(levels) == 6
    import json

    assert json.loads((out / "summary.json").read_text())["target_model"].startswith("body")


# Bad road files and arguments of farfield: tests/bad_inputs/cases.toml (in process).


@pytest.mark.parametrize(("rule", "lanes", "side"), [("RHT", (1, 2), -1.0), ("LHT", (-1, -2), 1.0)])
def test_far_field_looks_along_the_ego_lanes_travel(
    tmp_path: Path, system_b: System, rule: str, lanes: tuple[int, int], side: float
) -> None:
    """An ego on a lane that travels along -s (a left lane under right-hand traffic, a right
    lane under left-hand traffic) faces -s and looks along -s (hostile round eight: it
    faced +s, and an LHT road gave the RHT road's far field). By hand on the straight
    motorway_3lane (reference line along +x, lanes 3.75 m wide): at s = 900 the ego faces
    -x and the target lane's path runs from x = 900 towards x = 0, one lane (3.75 m) beside
    the ego on the outer side: its right under right-hand traffic, its left under
    left-hand traffic."""
    text = resolve_road("motorway_3lane").read_text(encoding="utf-8")
    road = tmp_path / "r.xodr"
    road.write_text(text.replace('rule="RHT"', f'rule="{rule}"', 1), encoding="utf-8")
    net = read_opendrive(road)
    setup = FarFieldSetup(
        road=str(road), ego_lane=lanes[0], target_lane=lanes[1], ego_s_m=900.0, length_m=200.0
    )
    pose = ego_pose(net, setup)
    assert abs(abs(pose.heading) - np.pi) < 1e-9  # facing -x
    assert abs(pose.x - 900.0) < 1e-9
    path = target_path(net, setup)
    assert path[0, 0] == pytest.approx(900.0, abs=1e-9)
    assert np.all(np.diff(path[:, 0]) < 0.0) and path[-1, 0] < 1.0
    _, ff = run_farfield(system_b, "clear", setup, net)
    # vehicle frame: ahead (x > 0), one lane to the outer side (y = -3.75 m: right)
    assert np.all(ff.vehicle[:, 0] > 0.0)
    assert np.allclose(ff.vehicle[:, 1], side * 3.75, atol=1e-9)
