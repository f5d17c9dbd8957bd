"""The batched evaluation path agrees with the single-scenario path and the exact models."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from sensorgap.config import load_environments, load_target
from sensorgap.coverage import GridSpec, Scene, evaluate_points
from sensorgap.coverage.logmiss import LogMissMaps, exact_log_miss, log_miss_of, lookup_log_miss
from sensorgap.models import Conditions, load_system
from sensorgap.scenarios import InfeasibleScenario, family_presets, load_family
from sensorgap.scenarios.batch import LaneTable, tracks_from_path
from sensorgap.scenarios.fastpath import track_extremes
from sensorgap.search.evaluate import DetectionRule, Evaluator, kinematics
from sensorgap.search.metrics import compute_all_batch, get_metric, metric_names
from sensorgap.search.problem import SearchProblem
from tests.search.metric_oracles import oracle
from tests.search.path_oracle import trajectory_from_path

ENVS = load_environments()


def _problem(
    family: str, mode: str = "exact", system: str = "system_b", rule: DetectionRule | None = None
) -> SearchProblem:
    envs = {k: ENVS[k] for k in ("clear", "glare_front_right", "fog_50")}
    return SearchProblem(load_family(family), envs, Evaluator(load_system(system), mode, rule=rule))


@pytest.mark.parametrize("name", family_presets())
def test_batch_rows_equal_single_generation(name: str) -> None:
    fam = load_family(name)
    prob = _problem(name)
    d = prob.decode_batch(np.random.default_rng(3).random((24, prob.dim)))
    batch = fam.generate_batch(d.params)
    for i, cand in enumerate(prob.candidates(d)):
        if not batch.ok[i]:
            with pytest.raises(InfeasibleScenario, match=batch.notes[i][:20]):
                fam.generate(cand.params)
            continue
        sc = fam.generate(cand.params)
        for who in ("ego", "target"):
            one, many = getattr(sc, who), getattr(batch, who)
            for a in ("x", "y", "heading", "speed"):
                np.testing.assert_array_equal(getattr(one, a), getattr(many, a)[i])


def test_decode_batch_equals_decode() -> None:
    prob = _problem("cut_in_left")
    U = np.random.default_rng(5).random((40, prob.dim))
    batch = prob.candidates(prob.decode_batch(U))
    assert batch == [prob.decode(u) for u in U]


def test_lane_table_matches_the_reader_within_sagitta() -> None:
    fam = load_family("slow_ahead_curve")
    tab = LaneTable(fam.network, "1", -1)
    s = np.linspace(0.0, tab.length, 20_001)
    x, y, h, _ = fam.network.lane_center("1", -1, s)
    xi, yi, hi = tab.poses(s, 1)
    # chord sagitta of 0.1 m steps on the 500 m arc: 0.1^2 / (8 * 500) = 2.5e-6 m
    assert np.max(np.hypot(x - xi, y - yi)) <= 3e-6
    assert np.max(np.abs(np.angle(np.exp(1j * (h - hi))))) <= 1e-6


@pytest.mark.parametrize("travel", [1, -1])
def test_lane_follower_heading_is_the_lanes(travel: int) -> None:
    """A lane follower's heading is the lane's in its travel direction (not the chord of
    its samples), its speed the central differences: on the 500 m arc at 30 m/s and
    20 Hz the chord heading agrees inside to the chord's half-step turn, and at the two
    one-sided ends to half a step's turn (1.5 m / 500 m / 2 = 1.5e-3 rad). The one-pass
    ``LaneTable.tracks`` gives the table's poses and the feasibility extremes of
    ``track_extremes`` exactly."""
    fam = load_family("slow_ahead_curve")
    tab = LaneTable(fam.network, "1", -1)
    t = np.arange(201) * 0.05
    s = 600.0 + travel * 30.0 * t[None, :] + np.array([[0.0], [7.3]])
    x, y, h = tab.poses(s, travel)
    lane = tab.tracks(s, travel, t)
    chord = tracks_from_path(t, x, y, h)
    np.testing.assert_array_equal(lane.x, x)
    np.testing.assert_array_equal(lane.y, y)
    np.testing.assert_array_equal(lane.heading, h)
    np.testing.assert_array_equal(lane.speed, chord.speed)
    ext = np.empty((2, 3))
    track_extremes(lane.heading, lane.speed, 0.05, ext)
    assert lane.extremes is not None
    np.testing.assert_array_equal(lane.extremes, ext)
    # 30 m/s of reference-line s; the lane's centre is 1.9 m off it on the 500 m arc
    assert ext[0, 0] == pytest.approx(30.0, rel=0.005)
    assert ext[0, 2] == pytest.approx(30.0**2 / 500.0, rel=0.05)  # v^2 / R on the arc
    dh = np.abs(lane.heading - chord.heading)[0]
    assert np.max(dh[1:-1]) <= 1e-5
    assert np.max(dh[[0, -1]]) == pytest.approx(1.5 / 500.0 / 2.0, rel=0.05)
    expected = math.atan2(y[0, 1] - y[0, 0], x[0, 1] - x[0, 0])
    assert abs(math.remainder(chord.heading[0, 0] - expected, 2.0 * math.pi)) <= 1e-12


def test_path_states_equal_trajectory_from_path_and_hand() -> None:
    """``fastpath.path_states`` (``tracks_from_path``) against the numpy
    ``Trajectory.from_path`` (np.gradient, np.unwrap) and by hand, at 20 Hz over 10 s:
    straight lines at 25 m/s (headings 0, 0.3, -2, pi and +-(pi - 1e-3), 300 m from the
    origin), circles at 20 m/s (R 50 m, crossing +-pi; R 15 m, 2.1 turns), a braking
    curve that stops and stands, an object standing still. Speed: atol 1e-12 m/s + rtol
    1e-12 against ``from_path`` (measured 1.3e-12 m/s at 25 m/s: np.gradient's formula
    for uneven spacing sees the rounding of t = k * 0.05); by hand rel 1e-12: the
    straight lines 25 m/s; on a circle the central differences give the chord speed,
    v sin(w dt) / (w dt) inside and v sin(w dt / 2) / (w dt / 2) at the one-sided ends
    (w = v / R; not v: 6.7e-5 lower on the 50 m circle). Heading: atol 1e-12 rad against
    ``from_path`` (measured 2.8e-13, unwrapped to 16 rad), where standing the fallback."""

    dt, n = 0.05, 201
    t = np.arange(n) * dt
    rows = []
    lines = (0.0, 0.3, -2.0, math.pi, math.pi - 1e-3, -math.pi + 1e-3)
    for th in lines:
        rows.append((300.0 + 25.0 * t * math.cos(th), -200.0 + 25.0 * t * math.sin(th), th))
    circles = ((50.0, 20.0, 2.5), (15.0, 20.0, 0.0))  # radius, speed, start angle
    for r, v, a0 in circles:
        a = a0 + v / r * t
        rows.append((100.0 + r * np.cos(a), -40.0 + r * np.sin(a), a + 0.5 * math.pi))
    s = np.where(t < 7.5, 30.0 * t - 2.0 * t**2, 112.5)  # brakes at 4 m/s2 to a stop
    rows.append((s, 3.0 * np.sin(s / 20.0), 0.1))
    rows.append((np.full(n, 5.0), np.full(n, -2.0), -2.5))
    x = np.array([r[0] for r in rows])
    y = np.array([r[1] for r in rows])
    fb = np.array([np.broadcast_to(r[2], t.shape) for r in rows])
    tr = tracks_from_path(t, x, y, fb)
    for i in range(len(rows)):
        ref = trajectory_from_path(t, x[i], y[i], fb[i])
        np.testing.assert_allclose(tr.speed[i], ref.speed, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(tr.heading[i], ref.heading, rtol=0, atol=1e-12)
    k = len(lines)
    np.testing.assert_allclose(tr.speed[:k], 25.0, rtol=1e-12, atol=0)
    for j, (r, v, _) in enumerate(circles):
        wdt = v / r * dt
        want = np.full(n, v * math.sin(wdt) / wdt)
        want[[0, -1]] = v * math.sin(0.5 * wdt) / (0.5 * wdt)
        np.testing.assert_allclose(tr.speed[k + j], want, rtol=1e-12, atol=0)
    assert abs(tr.speed[k, 5] - 20.0) > 1e-3  # the chord, not v
    stop = np.flatnonzero(t > 7.6)
    assert np.all(tr.speed[k + 2, stop] == 0.0) and np.all(tr.heading[k + 2, stop] == 0.1)
    assert np.all(tr.speed[-1] == 0.0) and np.all(tr.heading[-1] == -2.5)


def test_kinematics_by_hand() -> None:
    """Ego at 20 m/s behind a stopped car 50 m ahead (straight road): gap = 50 - half
    length - x_front, headway = gap / 20 s (the TTC is the encounter geometry's,
    tests/search/test_outcome.py)."""
    fam = load_family("slow_ahead_curve")
    sc = fam.generate(
        {"ego_s0_m": 450.0, "ego_speed_m_s": 20.0, "target_speed_m_s": 0.0, "gap0_m": 50.0}
    )
    system = load_system("system_a")
    car = load_target("car")
    kin = kinematics(sc, system, car)
    body = system.config.vehicle
    # the straight before the clothoid: the first step is exactly on a straight line
    gap = float(kin.x[0]) - 0.5 * car.length_m - body.x_front_m
    assert abs(float(kin.x[0]) - 50.0) < 1e-6
    assert kin.headway[0] == pytest.approx(gap / 20.0, rel=1e-9)


def test_cos_sin_near_equals_numpy_cos_and_sin() -> None:
    """``fastkin.cos_sin_near`` (cos/sin of h from those of a nearby h0: angle addition
    with a Taylor series of d = h - h0 when |d| < 0.02 rad, truncation error < 1e-18; else
    cos/sin) against np.cos/np.sin. One step from exact cos/sin of h0, series branch
    (|d| < 0.02, ends and tiny d included, h0 in +-4 pi) and the other branch (|d| >=
    0.02, h0 NaN: the kernels' first step): atol 1e-15 (the float64 rounding of the
    angle addition, about 1 ulp, dominates the truncation; measured 2.2e-16). Chained as
    ``kinematics_kernel`` and ``outcome._geometry_kernel`` use it (each step from the
    previous step's result), over 401-step headings (20 s at 20 Hz) turning by up to
    0.02 rad a step, with some larger jumps: the rounding accumulates; bound 1e-14
    (measured 2.1e-15)."""
    from sensorgap.search.fastkin import cos_sin_near

    rng = np.random.default_rng(23)
    h0 = rng.uniform(-4.0 * math.pi, 4.0 * math.pi, 4000)
    d = rng.uniform(-0.02, 0.02, 4000)
    d[:6] = [0.0, 0.019999999, -0.019999999, 1e-300, -5e-17, 1e-9]
    far = rng.choice([-1.0, 1.0], 4000) * rng.uniform(0.02, 3.0, 4000)
    far[:2] = [0.02, -0.02]
    for h in (h0 + d, h0 + far):
        got = np.array(
            [cos_sin_near(a, b, math.cos(b), math.sin(b)) for a, b in zip(h, h0, strict=True)]
        )
        np.testing.assert_allclose(got[:, 0], np.cos(h), rtol=0, atol=1e-15)
        np.testing.assert_allclose(got[:, 1], np.sin(h), rtol=0, atol=1e-15)
    c, s = cos_sin_near(0.3, math.nan, 1.0, 0.0)  # no previous heading
    assert abs(c - np.cos(0.3)) <= 1e-15 and abs(s - np.sin(0.3)) <= 1e-15
    worst = 0.0
    for _ in range(40):
        steps = rng.uniform(-0.02, 0.02, 400) * rng.uniform(0.0, 1.0)
        steps[rng.integers(0, 400, 2)] = rng.uniform(-1.0, 1.0, 2)  # a jump: exact again
        hs = np.cumsum(np.r_[rng.uniform(-math.pi, math.pi), steps])
        c, s, last = 1.0, 0.0, math.nan
        got = np.empty((hs.size, 2))
        for k, hk in enumerate(hs):
            c, s = cos_sin_near(hk, last, c, s)
            last = hk
            got[k] = c, s
        worst = max(worst, np.max(np.abs(got - np.column_stack([np.cos(hs), np.sin(hs)]))))
    assert worst <= 1e-14


@pytest.mark.parametrize("heading_deg", [0.0, 35.0, 170.0, -100.0])
def test_per_point_glare_equals_a_scene_with_that_sun(heading_deg: float) -> None:
    """Exact evaluation with per-point sun directions = ``evaluate_points`` in a scene
    resolved for that ego heading (scalar glare weight), every sensor, 1e-12."""
    env = ENVS["glare_front_right"].model_copy(
        update={
            "sun": ENVS["glare_front_right"].sun.model_copy(
                update={"frame": "world", "azimuth_deg": 75.0}
            )
        }
    )
    system = load_system("system_b")
    car = load_target("car")
    h = math.radians(heading_deg)
    ref = Scene(system, car, Conditions.from_config(env, h))
    rng = np.random.default_rng(1)
    pts = np.column_stack(
        [
            rng.uniform(-30, 150, 400),
            rng.uniform(-20, 20, 400),
            np.full(400, car.reference_height_m),
        ]
    )
    want = log_miss_of(evaluate_points(ref, pts).pd).sum(axis=0)
    scene = Scene(system, car, Conditions(env=env, sun_direction=None))
    dirs = Conditions.sun_directions(env, np.full(400, h))
    got = exact_log_miss(scene, pts[:, 0], pts[:, 1], pts[:, 2], dirs)
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)
    glared = [e for e in ref.log["effects"] if ": glare:" in e]
    assert len(glared) >= 2  # every heading here puts the sun into some cameras


def test_lookup_is_exact_at_cell_centres_with_and_without_glare() -> None:
    """Bilinear lookup at grid nodes returns the node: the lookup equals exact evaluation
    there (float32 maps: 1e-5 relative), including the glared cameras."""
    env = ENVS["glare_front_right"]
    system = load_system("system_b")
    car = load_target("car")
    scene = Scene(system, car, Conditions(env=env, sun_direction=None))
    grid = GridSpec(-20.0, 80.0, -10.0, 10.0, 0.5, car.reference_height_m)
    maps = LogMissMaps.build(scene, grid)
    xs, ys = grid.xs()[3:-3:7], grid.ys()[3:-3:5]
    xx, yy = (a.ravel() for a in np.meshgrid(xs, ys))
    zz = np.full(xx.size, car.reference_height_m)
    for heading in (0.0, 1.2, -2.0):
        dirs = Conditions.sun_directions(env, np.full(xx.size, heading))
        exact = exact_log_miss(scene, xx, yy, zz, dirs)
        look, _ = lookup_log_miss(maps, scene, xx, yy, zz, dirs)
        np.testing.assert_allclose(look, exact, rtol=1e-5, atol=1e-5)


@pytest.mark.parametrize("rule", [DetectionRule(), DetectionRule(kind="m_of_n", m=3, n=5)])
def test_batch_metrics_equal_per_row_metrics(rule: DetectionRule) -> None:
    prob = _problem("cut_in_right", rule=rule)
    d = prob.decode_batch(np.random.default_rng(11).random((60, prob.dim)))
    batch = prob.family.generate_batch(d.params)
    ok = np.flatnonzero(batch.ok)
    bt = prob.evaluator.evaluate_batch(
        batch, d.env_names, prob.environments, d.sun_deg, rows=ok, duration_s=prob.family.duration_s
    )
    values = compute_all_batch(bt)
    for i in range(len(ok)):
        tr = bt.row(i)
        for m in metric_names():
            # the compiled batch pass against the reference formulas (metric_oracles) and
            # against the row as a batch of one (what compute_all of a trace evaluates)
            want = oracle(m, tr)
            assert values[m][i] == pytest.approx(want, rel=1e-12, abs=1e-12, nan_ok=True), m
            assert get_metric(m).compute(tr) == pytest.approx(
                values[m][i], rel=1e-12, abs=1e-12, nan_ok=True
            ), m


def test_threads_give_identical_results() -> None:
    prob = _problem("overtake_left", mode="lookup")
    d = prob.decode_batch(np.random.default_rng(2).random((300, prob.dim)))
    one = prob.evaluate_decoded(d, threads=1)
    two = prob.evaluate_decoded(d, threads=2)
    assert one.notes == two.notes
    np.testing.assert_array_equal(one.feasible, two.feasible)
    for m in one.metrics:
        np.testing.assert_array_equal(one.metrics[m], two.metrics[m])


def test_single_evaluate_equals_its_batch_row() -> None:
    prob = _problem("crossing_pedestrian", mode="lookup")
    d = prob.decode_batch(np.random.default_rng(4).random((30, prob.dim)))
    out = prob.evaluate_decoded(d)
    for i, cand in enumerate(prob.candidates(d)):
        r = prob.evaluate(cand)
        assert r.feasible == bool(out.feasible[i])
        assert out.objective is not None and r.objective == out.objective[i]
        for m in out.metrics:
            assert r.metrics[m] == out.metrics[m][i] or (
                np.isnan(r.metrics[m]) and np.isnan(out.metrics[m][i])
            ), m


@pytest.mark.parametrize("name", ["crossing_pedestrian", "crossing_cyclist"])
def test_crossing_waits_on_the_footway_and_meets_its_timing(name: str) -> None:
    """The target stays within the footway (2 m beyond the outermost lane), accelerates
    within its limits, and reaches the ego lane's centre at cross_ahead / v_ego + offset."""
    fam = load_family(name)
    prob = _problem(name)
    d = prob.decode_batch(np.random.default_rng(9).random((60, prob.dim)))
    batch = fam.generate_batch(d.params)
    net, rid = fam.network, str(fam.settings["road_id"])
    lane = int(fam.settings["ego_lane"])
    for i in np.flatnonzero(batch.ok):
        p = {k: v[i] for k, v in d.params.items()}
        xs, ys = batch.target.x[i], batch.target.y[i]
        assert np.max(net.off_road_m(xs, ys)) <= 2.0 + 1e-6
        _, lanes, _, t_road = net.world_to_road(xs, ys)
        t_p = float(p["cross_ahead_m"]) / float(p["ego_speed_m_s"]) + float(p["conflict_offset_s"])
        s_c = float(np.mean(net.world_to_road(xs, ys)[2]))
        inner, outer = net.lane_edges(rid, lane, np.array([s_c]))
        centre = 0.5 * float(inner[0] + outer[0])
        if 0.0 < t_p < batch.t[-1]:
            k = int(round(t_p * 20))
            assert abs(float(t_road[k]) - centre) <= float(p["target_speed_m_s"]) * 0.05 + 1e-6


def test_scene_limited_evaluation_is_identical_and_logged() -> None:
    """Scoped exact evaluation of point targets (only sensors that can reach the batch's
    region) gives the same metrics, bit for bit, as evaluating every sensor; the skipped
    sensors are logged (the ultrasonic sensors on a motorway curve). Bodies are culled per
    sensor and pose instead (tests/coverage/test_body.py)."""
    from sensorgap.search.problem import Decoded

    n = 10
    d = Decoded(
        np.array(["glare_front_right"] * n),
        np.column_stack([np.linspace(0, 350, n), np.full(n, 10.0)]),
        {
            "ego_s0_m": np.linspace(450.0, 700.0, n),
            "ego_speed_m_s": np.full(n, 15.0),
            "target_speed_m_s": np.full(n, 15.0),
            "gap0_m": np.linspace(100.0, 190.0, n),
        },
    )
    outs = []
    for scoped in (True, False):
        prob = SearchProblem(
            load_family("slow_ahead_curve"),
            {k: ENVS[k] for k in ("clear", "glare_front_right", "fog_50")},
            Evaluator(load_system("system_b"), "exact", bodies=False),
        )
        prob.evaluator.scoped = scoped
        # every row (the search itself evaluates Pd only where there is a collision to
        # avoid, and these keep their distance)
        bt = prob.evaluator.evaluate_batch(
            prob.family.generate_batch(d.params), d.env_names, prob.environments, d.sun_deg
        )
        outs.append((bt, prob.evaluator.scope_log))
    (a, log_a), (b, log_b) = outs
    assert np.all(a.log_miss < 0.0)
    np.testing.assert_array_equal(a.log_miss, b.log_miss)
    assert a.log_miss_confirm is not None and b.log_miss_confirm is not None
    np.testing.assert_array_equal(a.log_miss_confirm, b.log_miss_confirm)
    assert log_b == {}
    ultrasonic = {x.id for x in load_system("system_b").sensors if x.type_name == "ultrasonic"}
    assert ultrasonic and ultrasonic <= set(log_a)
    assert all("cannot reach" in v for v in log_a.values())


def test_pieces_and_threads_give_identical_results(monkeypatch: pytest.MonkeyPatch) -> None:
    """Splitting a batch into pieces (any size, any number of threads) changes nothing."""
    import sensorgap.search.problem as problem_module

    prob = _problem("slow_ahead_curve", mode="lookup")
    d = prob.decode_batch(np.random.default_rng(8).random((300, prob.dim)))
    whole = prob.evaluate_decoded(d, threads=1)
    monkeypatch.setattr(problem_module, "PIECE_ROWS", 37)
    for threads in (1, 2):
        got = prob.evaluate_decoded(d, threads=threads)
        assert got.notes == whole.notes
        np.testing.assert_array_equal(got.feasible, whole.feasible)
        assert got.objective is not None and whole.objective is not None
        np.testing.assert_array_equal(got.objective, whole.objective)
        for m in whole.metrics:
            np.testing.assert_array_equal(got.metrics[m], whole.metrics[m])


def test_distance_at_detection_is_not_capped() -> None:
    """issue #13: ``distance_at_detect_m`` was clipped to 99 (the TTC cap in seconds applied
    to metres). A car held 150 m ahead at the ego's speed on the straight, detected in the
    first frames: the distance at detection is about 150 m (rear axle to centre), per trace
    and per batch alike."""
    fam = load_family("slow_ahead_curve")
    p = {"ego_s0_m": 100.0, "ego_speed_m_s": 20.0, "target_speed_m_s": 20.0, "gap0_m": 150.0}
    sc = fam.generate(p)
    ev = Evaluator(load_system("system_a"), "exact")
    tr = ev.trace(sc, load_environments()["clear"], fam.duration_s)
    m = get_metric("distance_at_detect_m")
    assert m is not None
    d = m.compute(tr)
    assert 145.0 < d < 160.0
    from sensorgap.scenarios.batch import ScenarioBatch

    bt = ev.evaluate_batch(
        ScenarioBatch.of(sc), ["clear"], load_environments(), duration_s=fam.duration_s
    )
    assert m.compute_batch(bt)[0] == pytest.approx(d, abs=1e-9)


def test_lane_progress_and_row_bounds_equal_numpy() -> None:
    """``lane_progress`` equals the numpy expression ``s0 + travel * (offset + v t)`` bit
    for bit (both travel directions, offset 0 included) and ``row_bounds`` equals
    ``numpy.min`` / ``numpy.max`` along the rows, NaN rows included."""
    from sensorgap.scenarios.batch import lane_progress
    from sensorgap.scenarios.fastpath import row_bounds

    rng = np.random.default_rng(4)
    t = np.arange(201) / 20.0
    s0, off, v = (rng.uniform(-500.0, 900.0, (64, 1)) for _ in range(3))
    for travel in (1, -1):
        np.testing.assert_array_equal(
            lane_progress(s0, travel, off, v, t), s0 + travel * (off + v * t)
        )
        np.testing.assert_array_equal(lane_progress(s0, travel, 0.0, v, t), s0 + travel * v * t)
    s = rng.normal(size=(6, 9))
    s[2, 4] = np.nan
    s[5, 0] = np.nan
    lo, hi = np.empty(6), np.empty(6)
    row_bounds(s, lo, hi)
    np.testing.assert_array_equal(lo, np.min(s, axis=1))
    np.testing.assert_array_equal(hi, np.max(s, axis=1))


@pytest.mark.parametrize("family", ["slow_ahead_curve", "cut_in_behind_truck"])
def test_moving_only_sensors_in_one_pass_equal_two_passes(
    monkeypatch: pytest.MonkeyPatch, family: str
) -> None:
    """System B's radar confirms where the target moves (``confirm_moving_with``). Looked
    up in the same compiled pass as the confirming sensors (``lookup_log_miss_tracks``'s
    ``also``), the fused ln P_miss equals a pass of its own masked by the moving steps (the
    way for glare-prone moving-only sensors) bit for bit, with occluders too (the truck)."""
    import sensorgap.search.evaluate as evaluate_module

    prob = _problem(family, mode="lookup")
    assert prob.evaluator.moving_rows
    d = prob.decode_batch(np.random.default_rng(11).random((400, prob.dim)))
    batch = prob.family.generate_batch(d.params)
    rows = np.flatnonzero(batch.ok)

    def log_miss() -> np.ndarray:
        bt = prob.evaluator.evaluate_batch(
            batch, d.env_names, prob.environments, d.sun_deg, rows=rows, collisions_only=True
        )
        return np.asarray(bt.log_miss)

    one = log_miss()
    monkeypatch.setattr(evaluate_module, "also_glare_free", lambda *_: False)
    two = log_miss()
    assert np.count_nonzero(one) > 1000  # something was looked up
    np.testing.assert_array_equal(one, two)


@pytest.mark.parametrize("which", ["target_speed_m_s", "ego_speed_m_s"])
def test_a_crossing_with_a_standing_party_is_infeasible(which: str) -> None:
    """A crossing whose target or ego stands (speed 0, inside the documented 0..100 m/s
    bound of every speed; hostile round nine: evaluate divided by it and ended in an
    internal error) is an infeasible row with its reason, and no numpy warning (an error
    in this suite) is raised on the way; the other rows are untouched."""
    fam = load_family("crossing_pedestrian")
    p = {
        "ego_s0_m": np.array([90.0, 90.0]),
        "ego_speed_m_s": np.array([8.0, 8.0]),
        "cross_ahead_m": np.array([30.0, 30.0]),
        "target_speed_m_s": np.array([1.2, 1.2]),
        "conflict_offset_s": np.array([0.0, 0.0]),
        "side": np.array(["right", "right"]),
    }
    for still in (0.0, 1e-300):  # (1e-300: the timing overflowed)
        p[which] = np.array([still, p[which][1]])
        batch = fam.generate_batch(p)
        assert not batch.ok[0] and batch.ok[1]
    assert batch.notes[0] == (
        "a crossing needs the target and the ego to move (target_speed_m_s and "
        "ego_speed_m_s at least 0.01 m/s)"
    )


@pytest.mark.parametrize(
    ("which", "note"),
    [
        (
            "speed_delta_m_s",
            "an overtake needs the target faster than the ego (speed_delta_m_s > 0)",
        ),
        ("decel_m_s2", "the target's braking needs decel_m_s2 > 0"),
    ],
)
def test_an_overtake_that_cannot_happen_is_infeasible(which: str, note: str) -> None:
    """An overtake whose target is not faster than the ego, or cannot brake (0, within the
    documented bounds; a systematic check of every parameter at 0 found a division by zero,
    exit 1): an infeasible row with its reason, no numpy warning (an error here)."""
    fam = load_family("overtake_left")
    prob = _problem("overtake_left")
    d = prob.decode_batch(np.random.default_rng(5).random((2, prob.dim)))
    params = {k: np.asarray(v).copy() for k, v in d.params.items()}
    params[which] = np.array([0.0, params[which][1]])
    batch = fam.generate_batch(params)
    assert not batch.ok[0] and batch.notes[0] == note


@pytest.mark.parametrize("which", ["speed_delta_m_s", "decel_m_s2"])
@pytest.mark.parametrize("tiny", [5e-324, 1e-310])
def test_an_overtake_with_a_subnormal_speed_difference_or_braking(which: str, tiny: float) -> None:
    """A speed difference or deceleration of 5e-324 (the smallest float) passes the > 0
    guard and made the merge or braking time overflow (numpy's warning, an error here;
    hostile round 22). The merge, or the braking's end, then never comes; every position
    stays finite."""
    fam = load_family("overtake_left")
    prob = _problem("overtake_left")
    d = prob.decode_batch(np.random.default_rng(5).random((2, prob.dim)))
    params = {k: np.asarray(v).copy() for k, v in d.params.items()}
    params[which] = np.array([tiny, tiny])
    batch = fam.generate_batch(params)
    for track in (batch.ego, batch.target):
        assert all(np.all(np.isfinite(a)) for a in (track.x, track.y, track.speed))


def test_a_target_classes_largest_speed_comes_from_its_targets_file(tmp_path: Path) -> None:
    """``max_speed_m_s`` of the targets file bounds a family's target (hostile round 22:
    the search used a fixed table, so a car of 0.1 m/s top speed was ranked cutting in at
    20 m/s, and a pedestrian of 150 m/s was refused at 4 m/s)."""
    import re

    from sensorgap.config.presets import templates_dir
    from sensorgap.errors import InputError

    text = (templates_dir() / "targets.toml").read_text()
    car = tmp_path / "slow_car.toml"
    car.write_text(text.replace("max_speed_m_s = 70.0", "max_speed_m_s = 0.1", 1))
    with pytest.raises(InputError, match=r"above the largest speed of a car \(0\.1 m/s"):
        load_family("cut_in_left", targets=car)
    fast = tmp_path / "fast_walker.toml"
    fast.write_text(re.sub(r"(?m)^max_speed_m_s = 3\.0$", "max_speed_m_s = 150.0", text))
    family = (templates_dir() / "scenarios" / "crossing_pedestrian.toml").read_text()
    fam_path = tmp_path / "fast_ped.toml"
    fam_path.write_text(
        re.sub(r"(?m)^target_speed_m_s = .*$", "target_speed_m_s = [4.0, 10.0]", family)
    )
    with pytest.raises(InputError, match="above the largest speed of a pedestrian"):
        load_family(str(fam_path))
    assert load_family(str(fam_path), targets=fast).limits.max_speed == 150.0
    assert load_family("cut_in_left").limits.max_speed == 70.0  # the shipped file's
