"""Target bodies (``coverage.body``): a box half inside a field of view, by hand; the
culling changes nothing; the body of the issue's false weakness is seen."""

from __future__ import annotations

import math

import numpy as np
import pytest

import sensorgap.coverage.body as body_mod
from sensorgap.config import EnvironmentConfig, load_target
from sensorgap.coverage import Scene
from sensorgap.coverage.body import body_per_sensor_pd, body_points, body_samples
from sensorgap.coverage.logmiss import sensor_snr
from sensorgap.models import Conditions, load_system
from sensorgap.models.roc import detection_probability


@pytest.fixture(scope="module")
def scene_a() -> Scene:
    return Scene(
        load_system("system_a"),
        load_target("car"),
        Conditions(env=EnvironmentConfig(name="clear"), sun_direction=None),
    )


def _row(scene: Scene, sid: str) -> int:
    return [s.id for s in scene.sensors].index(sid)


def _fraction_by_hand(s, px, py, pz, nx, ny) -> float:
    """Facing samples inside a level, forward camera's view (|azimuth| <= HFOV/2,
    |elevation| <= VFOV/2, range within limits), counted directly."""
    m = s.mount
    facing = nx * (m.x - px) + ny * (m.y - py) > 0
    dx, dy, dz = px - m.x, py - m.y, pz - m.z
    r = np.sqrt(dx * dx + dy * dy + dz * dz)
    inside = (
        (np.abs(np.arctan2(dy, dx)) <= 0.5 * m.hfov)
        & (np.abs(np.arctan2(dz, np.hypot(dx, dy))) <= 0.5 * m.vfov)
        & (r >= m.min_range)
        & (r <= m.max_range)
    )
    return float((facing & inside).sum() / facing.sum())


def test_box_partly_inside_the_windshield_camera(scene_a):
    # cam_windshield: level, yaw 0, HFOV 50 deg. A car 40 m ahead, heading 0, moved
    # sideways across the left edge of the view: the visible fraction of its facing outline
    # is counted by hand; the camera detects it only from half on (MIN_VISIBLE_FRACTION),
    # then with Pd = ROC(best visible sample's SNR + 10 log10(fraction)) (point model SNR)
    s = scene_a.sensors[_row(scene_a, "cam_windshield")]
    assert s.mount.pitch == 0.0 and s.mount.yaw == 0.0
    b = body_samples(scene_a.target)
    x_face = 40.0 - 2.25
    edge = s.mount.y + math.tan(0.5 * s.mount.hfov) * (x_face - s.mount.x)
    seen = {"below": False, "above": False}
    for shift in np.linspace(-2.0, 4.0, 25):
        yc = edge + shift
        pd, frac = body_per_sensor_pd(
            scene_a, np.array([40.0]), np.array([yc]), np.array([0.0]), sensors=(s,)
        )
        px, py, pz, nx, ny = body_points(b, np.array([40.0]), np.array([yc]), np.array([0.0]))
        f = _fraction_by_hand(s, px[0], py[0], pz[0], nx[0], ny[0])
        assert frac[0, 0] == pytest.approx(f, abs=1e-12)
        if 0.0 < f < 0.5:
            seen["below"] = True
            assert pd[0, 0] == 0.0
        elif f >= 0.5:
            seen["above"] = True
            facing = nx[0] * (s.mount.x - px[0]) + ny[0] * (s.mount.y - py[0]) > 0
            _, snr = sensor_snr(scene_a, s, px[0][facing], py[0][facing], pz[0][facing])
            want = detection_probability(
                np.array([snr.max() + 10 * math.log10(f)]), s.roc, scene_a.roc_shift_db
            )[0]
            assert pd[0, 0] == pytest.approx(want, abs=1e-12)
    assert seen == {"below": True, "above": True}


def test_radar_needs_only_a_reflecting_part(scene_a):
    # the same half-in-view pose for the front radar's field of view: any visible sample
    # counts, with the cross-section scaled by the visible fraction (-10 log10(1/f) dB)
    s = scene_a.sensors[_row(scene_a, "radar_front_center")]
    x_face = 60.0 - 2.25
    yc = s.mount.y + math.tan(0.5 * s.mount.hfov) * (x_face - s.mount.x)
    pd, frac = body_per_sensor_pd(
        scene_a, np.array([60.0]), np.array([yc]), np.array([0.0]), sensors=(s,)
    )
    assert 0.0 < frac[0, 0] < 1.0
    b = body_samples(scene_a.target)
    px, py, pz, nx, ny = body_points(b, np.array([60.0]), np.array([yc]), np.array([0.0]))
    facing = (nx * (s.mount.x - px) + ny * (s.mount.y - py)) > 0
    idx, snr = sensor_snr(scene_a, s, px[facing], py[facing], pz[facing])
    assert frac[0, 0] == pytest.approx(idx.size / facing.sum(), abs=1e-12)
    want = detection_probability(
        np.array([snr.max() + 10 * math.log10(frac[0, 0])]), s.roc, scene_a.roc_shift_db
    )[0]
    assert pd[0, 0] == pytest.approx(want, abs=1e-12)


def test_culling_changes_nothing(scene_a, monkeypatch):
    rng = np.random.default_rng(7)
    x = rng.uniform(-30, 80, 400)
    y = rng.uniform(-25, 25, 400)
    x[:100], y[:100] = rng.uniform(-6, 8, 100), rng.uniform(-4, 4, 100)  # beside the ego
    psi = rng.uniform(-math.pi, math.pi, 400)
    culled = body_per_sensor_pd(scene_a, x, y, psi)
    monkeypatch.setattr(body_mod, "CULL", False)
    full = body_per_sensor_pd(scene_a, x, y, psi)
    np.testing.assert_array_equal(culled[0], full[0])
    np.testing.assert_array_equal(culled[1], full[1])


def test_issue_false_weakness_is_seen(scene_a):
    # issue #13: centre (2.2, -2.3) in a side blind spot (Pd 0 as a point) while the body
    # is plainly seen by the right mirror camera, the rear-right radar and ultrasonics
    pd, _ = body_per_sensor_pd(scene_a, np.array([2.2]), np.array([-2.3]), np.array([0.0]))
    fused = 1.0 - np.prod(1.0 - pd[:, 0])
    assert fused > 0.99
    assert pd[_row(scene_a, "cam_mirror_right"), 0] > 0.9


def test_hidden_by_the_ego_body(scene_a):
    # a lidar on the roof cannot see a low sample right beside the car through the roof:
    # the segment from the mount to a point 0.2 m high just outside the right side passes
    # through the ego's box when the lidar sits above the box's centre line
    lid = scene_a.sensors[_row(scene_a, "lidar_front")]
    lo, hi = body_mod._ego_box(scene_a)
    inside = all(lo[a] < v < hi[a] for a, v in enumerate((lid.mount.x, lid.mount.y, lid.mount.z)))
    mz = max(lid.mount.z, hi[2] + 0.1)
    assert body_mod._hidden_by_box(lid.mount.x, lid.mount.y, mz, 1.0, -1.5, 0.2, lo, hi)
    # the same sample seen from beside the car, at its own height: not hidden
    assert not body_mod._hidden_by_box(1.0, -3.0, 0.2, 1.0, -1.5, 0.2, lo, hi)
    assert not inside or lid.mount.z < hi[2]  # where the preset puts it
    # and through the body model: the facing sample is counted, but not visible
    flat = np.empty(1, dtype=np.int64)
    nf = np.empty(1, dtype=np.int64)
    mount = np.array(
        [lid.mount.x, lid.mount.y, mz, 1.0, 0.0, 1.0, 0.0, -1.0, -1.0, 0.0, 1e3, math.pi]
    )
    got = body_mod._view_kernel(
        np.array([[1.0]]),
        np.array([[-1.5]]),
        np.array([[0.2]]),
        np.array([[0.0]]),
        np.array([[1.0]]),
        np.array([0], dtype=np.int64),
        mount,
        lo,
        hi,
        True,
        True,
        np.zeros((1, 0, 7)),
        flat,
        nf,
    )
    assert nf[0] == 1 and got == 0


def test_body_points_are_the_samples_rotated_and_moved(scene_a):
    """``body_points`` (``body._points_kernel``, ``place_sample``) against the rotation
    and translation written out in numpy: position = centre + R(psi) (bx, by), normal =
    R(psi) (nx, ny), z unchanged, for random poses and headings 0, +-pi/2, +-pi and past
    +-pi; positions to 1e-12 m, normals to 1e-15. By hand from the car's length and width:
    at heading pi/2 the front face (normal +x) lies at y + length/2 facing +y, across
    x -+ half the width."""
    body = body_samples(scene_a.target)
    rng = np.random.default_rng(17)
    n = 64
    x = rng.uniform(-120.0, 120.0, n)
    y = rng.uniform(-60.0, 60.0, n)
    psi = rng.uniform(-math.pi, math.pi, n)
    psi[:8] = [0.0, 0.5 * math.pi, -0.5 * math.pi, math.pi, -math.pi, 4.0, -4.0, 3.0 * math.pi]
    px, py, pz, nx, ny = body_points(body, x, y, psi)
    k = len(body)
    assert px.shape == py.shape == pz.shape == nx.shape == ny.shape == (n, k)
    rot = np.empty((n, 2, 2))
    rot[:, 0, 0], rot[:, 0, 1] = np.cos(psi), -np.sin(psi)
    rot[:, 1, 0], rot[:, 1, 1] = np.sin(psi), np.cos(psi)
    pos = np.einsum("nab,bk->nak", rot, np.stack([body.x, body.y]))
    nrm = np.einsum("nab,bk->nak", rot, np.stack([body.nx, body.ny]))
    np.testing.assert_allclose(px, x[:, None] + pos[:, 0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(py, y[:, None] + pos[:, 1], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(pz, np.broadcast_to(body.z, (n, k)))
    np.testing.assert_allclose(nx, nrm[:, 0], rtol=0, atol=1e-15)
    np.testing.assert_allclose(ny, nrm[:, 1], rtol=0, atol=1e-15)
    # by hand: a car at (10, -3) heading pi/2
    car = scene_a.target
    half_l, half_w = 0.5 * car.length_m, 0.5 * car.width_m
    pose = np.array([10.0]), np.array([-3.0]), np.array([0.5 * math.pi])
    px, py, _, nx, ny = body_points(body, *pose)
    front = (body.nx == 1.0) & (body.ny == 0.0)
    assert front.sum() >= 2
    np.testing.assert_allclose(py[0, front], -3.0 + half_l, rtol=0, atol=1e-12)
    np.testing.assert_allclose(px[0, front], 10.0 - body.y[front], rtol=0, atol=1e-12)
    assert np.all(np.abs(px[0, front] - 10.0) < half_w)
    np.testing.assert_allclose(nx[0, front], 0.0, rtol=0, atol=1e-15)
    np.testing.assert_allclose(ny[0, front], 1.0, rtol=0, atol=1e-15)
    # every sample on the turned box's outline (heading pi/2: along the car is +y, its
    # left -x): |along| = half length or |across| = half width, inside the other extent
    along, across = py[0] + 3.0, 10.0 - px[0]
    on_end = np.isclose(np.abs(along), half_l, rtol=0, atol=1e-12)
    on_side = np.isclose(np.abs(across), half_w, rtol=0, atol=1e-12)
    assert np.all(on_end | on_side)
    assert np.all(np.abs(along) <= half_l + 1e-12) and np.all(np.abs(across) <= half_w + 1e-12)


def test_probe_and_coverage_with_heading(tmp_path, capsys):
    """``probe --heading`` and ``coverage --heading`` evaluate bodies: the issue's car
    beside the ego (centre in a side blind spot) is unseen as a point and seen as a body."""
    import csv

    from sensorgap.cli import main

    pts = tmp_path / "p.csv"
    pts.write_text("x,y\n2.2,-2.3\n")
    assert (
        main(
            [
                "probe",
                "--vehicle",
                "system_a",
                "--environment",
                "clear",
                "--target",
                "car",
                "--points",
                str(pts),
                "--out",
                str(tmp_path / "point.csv"),
            ]
        )
        == 0
    )
    assert (
        main(
            [
                "probe",
                "--vehicle",
                "system_a",
                "--environment",
                "clear",
                "--target",
                "car",
                "--points",
                str(pts),
                "--heading",
                "0",
                "--out",
                str(tmp_path / "body.csv"),
            ]
        )
        == 0
    )
    point = next(
        csv.DictReader(
            (tmp_path / "point.csv").read_text(encoding="utf-8").splitlines(keepends=True)
        )
    )
    body = next(
        csv.DictReader(
            (tmp_path / "body.csv").read_text(encoding="utf-8").splitlines(keepends=True)
        )
    )
    assert float(point["pd"]) == 0.0
    assert float(body["pd"]) > 0.99
    assert float(body["cam_mirror_right.visible"]) > 0.0
    out = tmp_path / "cov"
    assert (
        main(
            [
                "coverage",
                "--vehicle",
                "system_a",
                "--environment",
                "clear",
                "--target",
                "car",
                "--resolution",
                "1",
                "--extent",
                "-10,20,-8,8",
                "--heading",
                "90",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    summary = (out / "summary.json").read_text()
    assert "heading 90 deg" in summary
    assert (
        main(
            [
                "coverage",
                "--vehicle",
                "system_a",
                "--environment",
                "clear",
                "--target",
                "car",
                "--resolution",
                "1",
                "--extent",
                "-10,20,-8,8",
                "--heading",
                "nan",
                "--out",
                str(tmp_path / "bad"),
            ]
        )
        == 2
    )


def test_equal_headings_give_identical_body_maps() -> None:
    """360 and -360 deg are 0 deg, -90 is 270 (hostile round eight: at cells where the
    target's box touches the ego's body, 360 deg gave Pd 0 against 0.99999996 at 0 deg,
    from sin(2 pi) = -2.4e-16). The cells (1.5, +-1.5) m are those cells."""
    from sensorgap.coverage.grid import GridSpec
    from sensorgap.coverage.outputs import compute_coverage
    from tests.conftest import make_scene

    scene = make_scene(load_system("system_b"))
    grid = GridSpec(-4.0, 8.0, -4.0, 4.0, 1.0, 0.0)

    def fused(heading_deg: float) -> np.ndarray:
        return np.asarray(compute_coverage(scene, grid, False, 1, heading_deg).fused)

    zero = fused(0.0)
    for same in (360.0, -360.0):
        assert np.array_equal(fused(same), zero)
    assert np.array_equal(fused(-90.0), fused(270.0))
    assert np.array_equal(fused(-180.0), fused(180.0))
