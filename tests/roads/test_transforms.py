"""road <-> world transforms: exact round trips (< 1e-6 m) and the lane found."""

from __future__ import annotations

import time

import numpy as np
import pytest

from sensorgap.errors import InputError
from sensorgap.roads import RoadNetwork

ROUND_TRIP_TOL = 1e-6  # m


def _round_trip(net: RoadNetwork, road_id: str, half_width: float, n: int, seed: int) -> float:
    rng = np.random.default_rng(seed)
    length = net.road(road_id).length
    s = rng.uniform(0.0, length, n)
    t = rng.uniform(-half_width, half_width, n)
    x, y = net.road_to_world(road_id, s, t)
    t0 = time.perf_counter()
    rid, lane, s2, t2 = net.world_to_road(x, y)
    elapsed = time.perf_counter() - t0
    assert set(rid.tolist()) == {road_id}
    np.testing.assert_allclose(s2, s, atol=ROUND_TRIP_TOL, rtol=0)
    np.testing.assert_allclose(t2, t, atol=ROUND_TRIP_TOL, rtol=0)
    np.testing.assert_array_equal(lane, net.lane_at(road_id, s, t))
    return elapsed


def test_motorway_round_trip_10k_points(motorway: RoadNetwork) -> None:
    elapsed = _round_trip(motorway, "1", 7.49, 10_000, seed=1)
    assert elapsed < 5.0  # vectorised: ~0.05 s on a laptop


def test_rural_round_trip_through_clothoids(rural: RoadNetwork) -> None:
    _round_trip(rural, "1", 6.99, 5_000, seed=2)
    # every lane of both lane ids is hit: -1 right of the reference line, 1 left
    rid, lane, s, t = rural.world_to_road(
        *rural.road_to_world("1", np.full(2, 900.0), np.array([-1.75, 1.75]))
    )
    assert lane.tolist() == [-1, 1]
    np.testing.assert_allclose(s, 900.0, atol=ROUND_TRIP_TOL)


def test_scalars_in_scalars_out(motorway: RoadNetwork) -> None:
    x, y = motorway.road_to_world(1, 250.0, -1.875)
    assert isinstance(x, float) and (x, y) == pytest.approx((250.0, -1.875), abs=1e-12)
    rid, lane, s, t = motorway.world_to_road(250.0, -1.875)
    assert (rid, lane) == ("1", -1)
    assert (s, t) == pytest.approx((250.0, -1.875), abs=ROUND_TRIP_TOL)
    xr, yr, hr = motorway.reference_line("1", 500.0)
    assert (xr, yr, hr) == (500.0, 0.0, 0.0)


def test_points_off_the_lanes_get_lane_zero(motorway: RoadNetwork) -> None:
    rid, lane, s, t = motorway.world_to_road(np.array([250.0, -50.0]), np.array([-20.0, 1.0]))
    assert rid.tolist() == ["1", "1"] and lane.tolist() == [0, 0]
    assert s[0] == pytest.approx(250.0, abs=ROUND_TRIP_TOL)  # beside the road: perpendicular
    assert t[0] == pytest.approx(-20.0, abs=ROUND_TRIP_TOL)
    assert s[1] == 0.0  # before the road start: clamped to s = 0


def test_junction_points_map_back_to_themselves(urban: RoadNetwork) -> None:
    rng = np.random.default_rng(3)
    px, py = rng.uniform(-30.0, 30.0, 4000), rng.uniform(-30.0, 30.0, 4000)
    rid, lane, s, t = urban.world_to_road(px, py)
    on_lane = lane != 0
    assert 0.3 < on_lane.mean() < 0.95
    for r in set(rid[on_lane].tolist()):
        m = on_lane & (rid == r)
        x, y = urban.road_to_world(r, s[m], t[m])
        np.testing.assert_allclose(x, px[m], atol=ROUND_TRIP_TOL)
        np.testing.assert_allclose(y, py[m], atol=ROUND_TRIP_TOL)
        np.testing.assert_array_equal(lane[m], urban.lane_at(r, s[m], t[m]))
    # the junction centre lies on connecting roads (junction 100), on a driving lane
    r0, l0, _, _ = urban.world_to_road(0.0, 0.0)
    assert urban.road(r0).junction == "100" and l0 == -1


def test_arm_lane_centres_are_found_on_their_arm(urban: RoadNetwork) -> None:
    s = np.linspace(1.0, 99.0, 50)
    for arm in ("1", "2", "3", "4"):
        for lane in (-2, -1, 1, 2):
            x, y, _, _ = urban.lane_center(arm, lane, s)
            rid, lid, s2, _ = urban.world_to_road(x, y)
            assert set(rid.tolist()) == {arm} and set(lid.tolist()) == {lane}
            np.testing.assert_allclose(s2, s, atol=ROUND_TRIP_TOL)


def test_non_finite_points_are_input_errors(motorway: RoadNetwork) -> None:
    with pytest.raises(InputError, match="finite"):
        motorway.world_to_road(np.array([1.0, np.nan]), np.array([0.0, 0.0]))
    with pytest.raises(InputError, match="t must be finite"):
        motorway.road_to_world(1, 10.0, float("inf"))
