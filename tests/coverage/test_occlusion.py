"""Occlusion by other road users (issue #17, ``coverage.occluders``): a box behind a box
counted by hand, heights, adding an occluder never raises Pd, the switch-off is the
paper's empty road, and ``coverage --occluder`` draws the shadow."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from sensorgap.config import EnvironmentConfig, load_target
from sensorgap.coverage import Scene
from sensorgap.coverage import body as body_mod
from sensorgap.coverage.body import body_per_sensor_pd, body_points, body_samples
from sensorgap.coverage.occluders import Occluder, occluder_array, shadow_polygon
from sensorgap.models import Conditions, load_system


def _scene(target: str = "car") -> Scene:
    return Scene(
        load_system("system_a"),
        load_target(target),
        Conditions(env=EnvironmentConfig(name="clear"), sun_direction=None),
    )


def _row(scene: Scene, sid: str) -> int:
    return [s.id for s in scene.sensors].index(sid)


def _hidden_by_hand(
    m: tuple[float, float, float], p: np.ndarray, x1: float, x2: float, half_w: float, h: float
) -> bool:
    """An axis-aligned box x1..x2, |y| <= half_w, 0..h ahead of the mount (x1 > mount x,
    sample beyond x2): the ray crosses the slab x1..x2 for t in [ta, tb]; it is hidden
    when y(t) and z(t) are inside the box for a common t (interval arithmetic, not the
    model's slab loop)."""
    mx, my, mz = m
    dx, dy, dz = p[0] - mx, p[1] - my, p[2] - mz
    ta, tb = (x1 - mx) / dx, (x2 - mx) / dx
    lo, hi = max(ta, 0.0), min(tb, 1.0)

    def window(o: float, d: float, a: float, b: float) -> tuple[float, float]:
        if d == 0.0:
            return (-math.inf, math.inf) if a < o < b else (math.inf, -math.inf)
        t1, t2 = (a - o) / d, (b - o) / d
        return min(t1, t2), max(t1, t2)

    for o, d, a, b in ((my, dy, -half_w, half_w), (mz, dz, 0.0, h)):
        w0, w1 = window(o, d, a, b)
        lo, hi = max(lo, w0), min(hi, w1)
    return lo < hi


@pytest.mark.parametrize("offset_y", [0.0, 0.9, 1.6, 2.4])
def test_box_behind_box_visible_fraction_by_hand(offset_y: float) -> None:
    """A car 40 m ahead behind a 2.5 m wide, 3.5 m high box at 20-26 m (a van), shifted
    sideways by ``offset_y``: the windscreen camera's visible fraction equals the facing
    samples whose rays miss the box, counted by hand; Pd falls to 0 below the camera's
    minimum visible fraction (0.5)."""
    scene = _scene()
    row = _row(scene, "cam_windshield")
    cam = scene.sensors[row]
    occ = Occluder(23.0, 0.0, 0.0, 6.0, 2.5, 3.5)
    x, y, psi = np.array([40.0]), np.array([offset_y]), np.array([0.0])
    px, py, pz, nx, ny = body_points(body_samples(scene.target), x, y, psi)
    m = (cam.mount.x, cam.mount.y, cam.mount.z)
    facing = (nx * (m[0] - px) + ny * (m[1] - py) > 0.0)[0]
    hidden = np.array(
        [
            _hidden_by_hand(m, np.array([px[0, j], py[0, j], pz[0, j]]), 20.0, 26.0, 1.25, 3.5)
            for j in range(px.shape[1])
        ]
    )
    want = float((facing & ~hidden).sum() / facing.sum())  # all in view at 40 m ahead
    pd, frac = body_per_sensor_pd(scene, x, y, psi, occluders=occluder_array([occ]))
    assert frac[row, 0] == pytest.approx(want, abs=1e-12)
    pd0, frac0 = body_per_sensor_pd(scene, x, y, psi)
    assert frac0[row, 0] == pytest.approx(1.0)
    if want < 0.5:
        assert pd[row, 0] == 0.0
    else:
        assert 0.0 < pd[row, 0] <= pd0[row, 0]
    if offset_y == 0.0:
        assert want == 0.0  # wholly behind the van: no sensor ahead sees any of it
        fused = 1.0 - np.prod(1.0 - pd[:, 0])
        assert fused == 0.0


def test_low_occluder_hides_the_lower_samples_only() -> None:
    """A 0.7 m high box (a low wall, x 14.0-14.4 m) just in front of a pedestrian 15 m
    ahead (front face at 14.8 m): seen from the windscreen camera (1.32 m high) the rays
    to the samples at 25 % of 1.8 m (0.45 m) cross the wall at 0.45-0.51 m (hidden), those
    at 75 % (1.35 m) at about 1.35 m (seen): the visible fraction is 1/2."""
    scene = _scene("pedestrian")
    row = _row(scene, "cam_windshield")
    occ = Occluder(14.2, 0.0, 0.0, 0.4, 4.0, 0.7)
    pd, frac = body_per_sensor_pd(
        scene, np.array([15.0]), np.array([0.0]), np.array([0.0]), occluders=occluder_array([occ])
    )
    assert frac[row, 0] == pytest.approx(0.5)
    # a 1.5 m parked car instead hides the whole adult from the 1.32 m camera
    car = Occluder.of_target(load_target("car"), 12.0, 0.0, math.pi / 2)
    _, frac = body_per_sensor_pd(
        scene, np.array([15.0]), np.array([0.0]), np.array([0.0]), occluders=occluder_array([car])
    )
    assert frac[row, 0] == 0.0


def test_adding_an_occluder_never_raises_pd() -> None:
    """Random bodies and random occluders: every sensor's Pd with one occluder <= without,
    with two <= with one; visible fractions likewise."""
    scene = _scene()
    rng = np.random.default_rng(3)
    n = 3000
    x, y = rng.uniform(-40, 80, n), rng.uniform(-20, 20, n)
    psi = rng.uniform(-math.pi, math.pi, n)
    o1 = Occluder(rng.uniform(8, 30), rng.uniform(-6, 6), rng.uniform(0, math.pi), 10.0, 2.5, 4.0)
    o2 = Occluder(rng.uniform(-30, -8), rng.uniform(-6, 6), rng.uniform(0, math.pi), 4.5, 1.8, 1.5)
    p0, f0 = body_per_sensor_pd(scene, x, y, psi)
    p1, f1 = body_per_sensor_pd(scene, x, y, psi, occluders=occluder_array([o1]))
    p2, f2 = body_per_sensor_pd(scene, x, y, psi, occluders=occluder_array([o1, o2]))
    assert np.all(p1 <= p0) and np.all(p2 <= p1)
    assert np.all(f1 <= f0) and np.all(f2 <= f1)
    assert np.sum(p1 < p0) > 100  # the occluders do hide something
    # switched off (None or no boxes) = the empty road, bit for bit
    pe, fe = body_per_sensor_pd(scene, x, y, psi, occluders=occluder_array([]))
    np.testing.assert_array_equal(pe, p0)
    np.testing.assert_array_equal(fe, f0)
    # per-pose occluders: the same boxes repeated per pose give the same values
    per = np.repeat(occluder_array([o1])[None], n, axis=0)
    pp, _ = body_per_sensor_pd(scene, x, y, psi, occluders=per)
    np.testing.assert_array_equal(pp, p1)


def test_shadow_polygon_by_hand() -> None:
    """A 2 m wide box centred 10 m ahead seen from the origin: the shadow's near edge is
    the box's silhouette, its far corners lie on the rays through the silhouette corners at
    the reach."""
    occ = Occluder(10.0, 0.0, 0.0, 2.0, 2.0, 2.0)
    poly = shadow_polygon(occ, (0.0, 0.0), 100.0)
    near = {tuple(np.round(p, 9)) for p in poly[:2]}
    assert near == {(9.0, 1.0), (9.0, -1.0)}
    for p in poly[2:]:
        assert math.hypot(*p) == pytest.approx(100.0)
        assert abs(p[1] / p[0]) == pytest.approx(1.0 / 9.0)


def test_coverage_cli_with_an_occluder(tmp_path) -> None:
    """``coverage --heading 0 --occluder truck@15,-3.5,0``: cells in the truck's shadow
    seen without it lose Pd; the summary names the occluder; the map is drawn."""
    from sensorgap.cli import main

    common = [
        "coverage",
        "--vehicle",
        "system_a",
        "--environment",
        "clear",
        "--target",
        "car",
        "--extent",
        "-10,80,-15,15",
        "--resolution",
        "1",
        "--heading",
        "0",
    ]
    assert main([*common, "--out", str(tmp_path / "a")]) == 0
    assert main([*common, "--occluder", "truck@15,-3.5,0", "--out", str(tmp_path / "b")]) == 0
    a = np.load(tmp_path / "a" / "coverage.npz")["pd"]
    b = np.load(tmp_path / "b" / "coverage.npz")["pd"]
    assert np.all(b <= a)
    xs = np.load(tmp_path / "b" / "coverage.npz")["x"]
    ys = np.load(tmp_path / "b" / "coverage.npz")["y"]
    # a shadow: cells that lose at least half their Pd, all beyond the truck's front and
    # on its side of the ego (the rays from the front mounts pass through it)
    lost = (a - b) > 0.5
    assert lost.sum() >= 20
    yy, xx = np.meshgrid(ys, xs, indexing="ij")
    assert np.all(xx[lost] > 10.0 - 2.5) and np.all(yy[lost] < -1.0)
    s = json.loads((tmp_path / "b" / "summary.json").read_text())
    assert s["occluders"][0]["label"] == "truck"
    assert (tmp_path / "b" / "coverage.png").stat().st_size > 10_000


def test_occluder_overlaps_the_ego_footprint() -> None:
    """``Occluder.overlaps``: boxes against a 4 x 2 m footprint (x -1..3, y -1..1): inside,
    across an edge, rotated with a corner inside -> overlap; beside it, touching an edge or
    a corner only -> none; a diamond (a square at 45 deg) whose bounding box overlaps the
    footprint's corner but which stops short of it -> none (only its own axes separate)."""
    foot = [(-1.0, -1.0), (3.0, -1.0), (3.0, 1.0), (-1.0, 1.0)]

    def box(x: float, y: float, heading_deg: float = 0.0, side: float | None = None) -> Occluder:
        length, width = (2.0, 1.0) if side is None else (side, side)
        return Occluder(x, y, math.radians(heading_deg), length, width, 1.0)

    assert box(0.0, 0.0).overlaps(foot)
    assert box(3.9, 0.0).overlaps(foot)  # 2.9..4.9: 0.1 m into the front
    assert box(1.0, 1.45).overlaps(foot)  # 0.05 m into the left side
    assert box(3.5, 1.2, 45.0).overlaps(foot)  # its corner (2.44, 0.85) is inside
    assert not box(4.0, 0.0).overlaps(foot)  # touches the front edge only
    assert not box(1.0, 1.5).overlaps(foot)  # touches the left edge only
    assert not box(4.0, 1.5).overlaps(foot)  # touches the front-left corner only
    assert not box(1.0, -3.0, 30.0).overlaps(foot)
    # diamonds of half-diagonal 1 m: |x - cx| + |y - cy| <= 1
    assert not box(3.8, 1.8, 45.0, math.sqrt(2.0)).overlaps(foot)  # corner (3, 1): 1.6
    assert box(3.4, 1.4, 45.0, math.sqrt(2.0)).overlaps(foot)  # corner (3, 1): 0.8


def test_coverage_cli_refuses_an_occluder_on_the_ego(tmp_path, capsys) -> None:
    """``--occluder truck@0,0,0`` stands on the ego itself: one line naming the option, exit
    2, nothing written; the same truck in the next lane is accepted (tested above)."""
    from sensorgap.cli import main

    out = tmp_path / "o"
    argv = [
        *("coverage", "--vehicle", "system_a", "--environment", "clear", "--target", "car"),
        *("--extent", "-10,20,-5,5", "--resolution", "1", "--heading", "0"),
        *("--occluder", "truck@15,-3.5,0", "--occluder", "truck@0,0,0", "--out", str(out)),
    ]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("sensorgap: error: --occluder: 'truck@0,0,0'")
    assert "overlaps the ego body" in err[0]
    assert not out.exists()


def _random_poses_and_boxes(
    xr: tuple[float, float],
    yr: tuple[float, float],
    bx: tuple[float, float],
    by: tuple[float, float],
    size: tuple[float, float, float],
    n: int = 4000,
    seed: int = 11,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``n`` random target poses (x in ``xr``, y in ``yr``, any heading) and per pose one
    random box of ``size`` (length, width, height, m) centred in ``bx`` x ``by``."""
    rng = np.random.default_rng(seed)
    x, y = rng.uniform(*xr, n), rng.uniform(*yr, n)
    psi = rng.uniform(-math.pi, math.pi, n)
    boxes = np.stack(
        [
            occluder_array(
                [Occluder(rng.uniform(*bx), rng.uniform(*by), rng.uniform(0, math.pi), *size)]
            )
            for _ in range(n)
        ]
    )
    return x, y, psi, boxes


def test_may_hide_never_misses_a_hiding_box() -> None:
    """Random boxes and bodies: wherever an occluder lowers some sensor's visible fraction,
    the conservative footprint test ``may_hide`` says it may hide the target."""
    from sensorgap.coverage.occluders import may_hide

    scene = _scene()
    x, y, psi, boxes = _random_poses_and_boxes(
        (-40, 80), (-20, 20), (-30, 60), (-12, 12), (6.0, 2.0, 2.5)
    )
    _, f0 = body_per_sensor_pd(scene, x, y, psi)
    _, f1 = body_per_sensor_pd(scene, x, y, psi, occluders=boxes)
    hidden = np.any(f1 < f0, axis=0)
    mount_r = max(math.hypot(s.mount.x, s.mount.y) for s in scene.sensors)
    flagged = may_hide(boxes, x, y, 0.5 * math.hypot(4.5, 1.8), mount_r)
    assert hidden.sum() > 50
    assert np.all(flagged[hidden])
    assert flagged.mean() < 0.9  # and it does rule out boxes


def test_occlusion_changes_is_exact_about_where_the_pd_changes(monkeypatch) -> None:
    """``occlusion_changes`` (the lookup's geometry pre-test): with its per-pose culling,
    with or without precomputed body points, it marks the same poses as without culling,
    and every pose whose Pd of some sensor drops with the occluder is marked (it may mark
    more: a hidden sample need not lower the Pd)."""
    from sensorgap.coverage import body as body_mod
    from sensorgap.coverage.body import occlusion_changes, take_points

    scene = _scene()
    x, y, psi, boxes = _random_poses_and_boxes(
        (-40, 90), (-15, 15), (-20, 40), (-6, 6), (12.0, 2.5, 4.0)
    )
    pts = body_points(body_samples(scene.target), x, y, psi)
    culled = occlusion_changes(scene, x, y, psi, boxes)
    np.testing.assert_array_equal(occlusion_changes(scene, x, y, psi, boxes, points=pts), culled)
    monkeypatch.setattr(body_mod, "CULL", False)
    np.testing.assert_array_equal(occlusion_changes(scene, x, y, psi, boxes), culled)
    monkeypatch.undo()
    assert 200 < culled.sum() < len(x)  # not vacuous
    p0, _ = body_per_sensor_pd(scene, x, y, psi)
    p1, _ = body_per_sensor_pd(scene, x, y, psi, occluders=boxes)
    assert not np.any(np.any(p1 < p0, axis=0) & ~culled)
    # precomputed points (and a subset of them) give the same Pd as computing them
    sub = np.flatnonzero(culled)
    ps, _ = body_per_sensor_pd(
        scene, x[sub], y[sub], psi[sub], occluders=boxes[sub], points=take_points(pts, sub)
    )
    np.testing.assert_array_equal(ps, p1[:, sub])


def test_occlusion_changes_marks_the_poses_by_hand(monkeypatch) -> None:
    """``occlusion_changes`` (``body._changes_kernel``) in a scene worked out by hand: the
    windscreen camera (mount x 2.05, y 0, z 1.32 m; level, forward, HFOV 50 deg, VFOV 28
    deg, range 0.5-120 m) and a van-sized box at x 20-26 m, |y| <= 1.25 m, 3.5 m high.
    Car bodies (4.5 x 1.8 x 1.5 m, samples at 0.375 and 1.125 m high) at:

    0. (40, 0), heading 0: squarely behind the box, in view: marked;
    1. (40, 15): in view (its outline 19-24 deg off the axis), every ray passes the box
       at y > 6 m: not marked;
    2. (12, 0): between the ego and the box (rear face at 9.75 m): not marked;
    3. (150, 0): squarely behind the box but beyond the camera's 120 m: not marked (the
       front radar, 250 m, and lidar, 150 m, do see it hidden: marked for all sensors);
    4. (-40, 0): behind the ego, out of view, the box ahead: not marked;
    5. (40, 0), heading 90 deg: crosswise behind the box (side face at 39.1 m, samples at
       |y| <= 1.69 m cross x 20-26 m at |y| <= 1.09 m): marked.

    The box's height decides in 3D: the lowest ray (to a 0.375 m sample of pose 0) is at
    z 0.845 m at x 20 m and 0.686 m at x 26 m (pose 5: 0.709 m), so a 0.8 m box still
    hides samples of poses 0 and 5 and a 0.5 m box none. Per-pose boxes: pose 0's box
    moved to y = -5 m hides nothing; pose 1's box put on its line of sight hides it. The
    per-pose culling switched off gives the same marks."""
    from sensorgap.coverage.body import occlusion_changes

    scene = _scene()
    cam = scene.sensors[_row(scene, "cam_windshield")]
    m = cam.mount
    assert (m.x, m.y, m.z, m.yaw, m.pitch, m.max_range) == (2.05, 0.0, 1.32, 0.0, 0.0, 120.0)
    x = np.array([40.0, 40.0, 12.0, 150.0, -40.0, 40.0])
    y = np.array([0.0, 15.0, 0.0, 0.0, 0.0, 0.0])
    psi = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.5 * math.pi])

    def van(h: float) -> np.ndarray:
        return occluder_array([Occluder(23.0, 0.0, 0.0, 6.0, 2.5, h)])

    marked = [True, False, False, False, False, True]
    for cull in (True, False):
        monkeypatch.setattr(body_mod, "CULL", cull)
        for h in (3.5, 0.8):
            got = occlusion_changes(scene, x, y, psi, van(h), sensors=[cam])
            np.testing.assert_array_equal(got, marked)
        got = occlusion_changes(scene, x, y, psi, van(0.5), sensors=[cam])
        np.testing.assert_array_equal(got, [False] * 6)
        got = occlusion_changes(scene, x, y, psi, van(3.5))  # every sensor
        np.testing.assert_array_equal(got, [True, False, False, True, False, True])
        per = np.repeat(van(3.5)[None], 6, axis=0)
        per[0] = occluder_array([Occluder(23.0, -5.0, 0.0, 6.0, 2.5, 3.5)])
        b = math.atan2(15.0, 40.0 - m.x)  # the bearing of pose 1
        per[1] = occluder_array(
            [Occluder(m.x + 22.0 * math.cos(b), 22.0 * math.sin(b), b, 6.0, 2.5, 3.5)]
        )
        got = occlusion_changes(scene, x, y, psi, per, sensors=[cam])
        np.testing.assert_array_equal(got, [False, True, False, False, False, True])
