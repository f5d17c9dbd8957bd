"""Near-field analysis: exact footprints against closed forms and brute force, hand-built
blind spots, exact vs grid convergence, the paper's Fig. 5 areas, deterministic outputs."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st

from sensorgap.analysis import nearfield as nf
from sensorgap.analysis.paper import NEARFIELD_TOLERANCE, PAPER_BLIND_SPOT_M2
from sensorgap.config import vehicle as vehicle_config
from sensorgap.models import System, load_system
from sensorgap.models.geometry import Mount, fov_mask, in_range, rotate_offsets

REPO = Path(__file__).resolve().parents[2]


def mount(
    x: float = 1.0,
    y: float = 0.5,
    z: float = 0.5,
    yaw: float = 30.0,
    pitch: float = 0.0,
    hfov: float = 70.0,
    vfov: float = 35.0,
    rmin: float = 0.15,
    rmax: float = 5.5,
) -> Mount:
    return Mount(
        x,
        y,
        z,
        math.radians(yaw),
        math.radians(pitch),
        math.radians(hfov),
        math.radians(vfov),
        rmin,
        rmax,
    )


# ----------------------------------------------------------------------- closed forms


def test_unpitched_any_height_footprint_is_annular_sector() -> None:
    m = mount()
    fp = nf.sensor_footprint_any_height(m)
    assert isinstance(fp, shapely.Polygon) and fp.is_valid
    half = 0.5 * m.hfov
    # the paper's annular sector between min and max range ...
    assert fp.area == pytest.approx(half * (m.max_range**2 - m.min_range**2), rel=1e-3)
    # ... exactly: the steepest ray (vfov/2) reaches min_range at a horizontal distance
    # min_range cos(vfov/2), the horizontal ray reaches max_range
    r_in = m.min_range * math.cos(0.5 * m.vfov)
    assert fp.area == pytest.approx(half * (m.max_range**2 - r_in**2), rel=1e-5)
    centre = shapely.Point(m.x, m.y)
    assert fp.exterior.distance(centre) == pytest.approx(r_in, abs=1e-6)  # chord
    assert shapely.hausdorff_distance(fp.exterior, centre) == pytest.approx(m.max_range, abs=1e-9)


def test_full_circle_sensor_is_an_annulus() -> None:
    m = mount(hfov=360.0, vfov=40.0, rmin=1.0, rmax=4.0)
    fp = nf.sensor_footprint_any_height(m)
    r_in = math.cos(math.radians(20.0))
    assert fp.is_valid
    assert fp.area == pytest.approx(math.pi * (16.0 - r_in**2), rel=1e-5)
    assert fp.contains(shapely.Point(m.x + 2.0, m.y))
    assert not fp.contains(shapely.Point(m.x + 0.5 * r_in, m.y))


def test_camera_sees_the_0p1m_plane_only_beyond_the_vfov_limit() -> None:
    cam = mount(x=2.0, y=0.0, z=1.3, yaw=0.0, hfov=50.0, vfov=28.0, rmin=0.5, rmax=120.0)
    fp = nf.sensor_footprint_at_height(cam, 0.1)
    r_in = (1.3 - 0.1) / math.tan(math.radians(14.0))
    r_out = math.sqrt(120.0**2 - 1.2**2)
    # (the sampled arc's chords lie up to r (1 - cos(dphi/2)) ~ 2e-6 m inside it)
    assert fp.exterior.distance(shapely.Point(cam.x, cam.y)) == pytest.approx(r_in, abs=1e-5)
    assert fp.area == pytest.approx(0.5 * cam.hfov * (r_out**2 - r_in**2), rel=1e-5)
    # at the mount height the same camera sees from its minimum range on
    fp_mount = nf.sensor_footprint_at_height(cam, 1.3)
    assert fp_mount.exterior.distance(shapely.Point(cam.x, cam.y)) == pytest.approx(0.5)
    # and above its reach nothing
    assert nf.sensor_footprint_at_height(cam, 130.0).is_empty


def test_footprints_are_computed_once_per_exact_mount(monkeypatch: pytest.MonkeyPatch) -> None:
    """The footprint memo: the same mount, kind and step give the same (immutable) area
    without computing it again; any other height, step, or a mount differing only by the
    sign of a zero is computed; the memo keeps at most ``FOOTPRINT_MEMO`` areas."""
    calls: list[Mount] = []
    polar = nf._polar_region

    def counted(m: Mount, fn: nf.PolarFn, dphi: float) -> nf.Area:
        calls.append(m)
        return polar(m, fn, dphi)

    monkeypatch.setattr(nf, "_polar_region", counted)
    monkeypatch.setattr(nf, "_memo", nf._Memo(lambda: nf.FOOTPRINT_MEMO))
    m = mount(yaw=0.0, x=0.0)
    a = nf.sensor_footprint_any_height(m)
    assert nf.sensor_footprint_any_height(m) is a and len(calls) == 1
    b = nf.sensor_footprint_at_height(m, 0.1)
    assert nf.sensor_footprint_at_height(m, 0.1) is b and len(calls) == 2
    assert b.area < a.area  # at one height it sees less than at any
    nf.sensor_footprint_any_height(m, (0.0, 3.0))
    nf.sensor_footprint_any_height(m, dphi_deg=0.2)
    nf.sensor_footprint_any_height(mount(yaw=-0.0, x=-0.0))
    assert len(calls) == 5
    monkeypatch.setattr(nf, "FOOTPRINT_MEMO", 3)
    for k in range(4):
        nf.sensor_footprint_at_height(m, 0.2 + 0.1 * k)
    assert len(nf._memo) == 3
    nf.sensor_footprint_at_height(m, 0.2)  # the oldest was dropped: computed again
    assert len(calls) == 10


def test_mount_outside_the_height_range_is_refused() -> None:
    with pytest.raises(ValueError, match="height range"):
        nf.sensor_footprint_any_height(mount(z=5.0))


# ----------------------------------------------------------------------- brute force


def _brute_force(m: Mount, px: np.ndarray, py: np.ndarray, zs: np.ndarray) -> np.ndarray:
    seen = np.zeros(px.shape, dtype=bool)
    for z in zs:
        xs, ys, zz = rotate_offsets(m, px - m.x, py - m.y, float(z) - m.z)
        seen |= fov_mask(m, xs, ys, zz) & in_range(m, np.sqrt(xs * xs + ys * ys + zz * zz))
    return seen


@pytest.mark.parametrize(
    "m",
    [
        mount(z=1.02, yaw=90.0, pitch=70.0, hfov=137.0, vfov=77.0, rmin=0.1, rmax=6.0),
        mount(z=0.6, yaw=0.0, pitch=15.0, hfov=137.0, vfov=100.0, rmin=0.1, rmax=5.0),
        mount(z=0.9, yaw=-140.0, pitch=-10.0, hfov=250.0, vfov=30.0, rmin=0.5, rmax=4.0),
        mount(z=1.5, yaw=10.0, pitch=85.0, hfov=60.0, vfov=40.0, rmin=0.0, rmax=3.0),
    ],
    ids=["mirror-down", "bumper-fisheye", "wide-up", "nadir"],
)
def test_pitched_footprints_match_brute_force(m: Mount) -> None:
    rng = np.random.default_rng(7)
    r = m.max_range + 0.3
    px, py = m.x + rng.uniform(-r, r, 3000), m.y + rng.uniform(-r, r, 3000)
    pts = shapely.points(px, py)
    fp = nf.sensor_footprint_any_height(m)
    assert fp.is_valid
    seen = _brute_force(m, px, py, np.linspace(0.0, 4.0, 4001))
    clear = shapely.distance(fp.boundary, pts) > 5e-3  # 1 mm height steps
    assert np.array_equal(shapely.contains(fp, pts)[clear], seen[clear])
    fz = nf.sensor_footprint_at_height(m, 0.1)
    seen_z = _brute_force(m, px, py, np.array([0.1]))
    clear_z = (shapely.distance(fz.boundary, pts) > 1e-6) if not fz.is_empty else clear | ~clear
    assert np.array_equal(shapely.contains(fz, pts)[clear_z], seen_z[clear_z])


@settings(max_examples=15, deadline=None)
@given(
    st.floats(-180.0, 180.0),
    st.floats(-60.0, 89.0),
    st.floats(1.0, 360.0),
    st.floats(1.0, 179.0),
    st.floats(0.0, 1.0),
    st.floats(0.05, 3.9),
)
def test_footprints_are_valid_finite_and_nested(
    yaw: float, pitch: float, hfov: float, vfov: float, rmin: float, z: float
) -> None:
    m = mount(z=z, yaw=yaw, pitch=pitch, hfov=hfov, vfov=vfov, rmin=rmin, rmax=5.0)
    fp = nf.sensor_footprint_any_height(m, dphi_deg=0.25)
    fz = nf.sensor_footprint_at_height(m, 0.1, dphi_deg=0.25)
    for g in (fp, fz):
        assert g.is_valid and math.isfinite(g.area) and g.area >= 0.0
    # what is seen at 0.1 m is seen at some height (up to the chord error of the samples)
    assert shapely.difference(fz, fp).area <= 5e-4 * max(fz.area, 1.0)


# ----------------------------------------------------------------------- hand-built holes


def _vehicle_with(tmp_path: Path, sensors: list[dict[str, float | str]]) -> System:
    """System A's body and devices with the given ultrasonic-device sensors."""
    head = (REPO / "templates" / "vehicles" / "system_a.toml").read_text().split("[[sensors]]")[0]
    blocks = "".join(
        f'[[sensors]]\nid = "{s["id"]}"\ndevice = "ultrasonic_70"\n'
        f"position_m = [{s['x']}, {s['y']}, 0.5]\nyaw_deg = {s['yaw']}\n"
        f"hfov_deg = {s['hfov']}\nvfov_deg = 20.0\nmin_range_m = 0.0\n"
        f'max_range_m = {s["range"]}\nsource = "test"\n\n'
        for s in sensors
    )
    path = tmp_path / "hand.toml"
    path.write_text(head + blocks)
    return load_system(path)


def test_triangular_hole_between_two_sectors_and_the_body(tmp_path: Path) -> None:
    # System A's body: x in [-1.13, 4.04], |y| <= 0.975. Two sensors on the left corners
    # looking left with 90 deg fields of view: the sector edges at 135 deg (front) and
    # 45 deg (rear) close a right isosceles triangle over the left side of the body.
    system = _vehicle_with(
        tmp_path,
        [
            {"id": "front", "x": 4.04, "y": 0.975, "yaw": 90.0, "hfov": 90.0, "range": 10.0},
            {"id": "rear", "x": -1.13, "y": 0.975, "yaw": 90.0, "hfov": 90.0, "range": 10.0},
        ],
    )
    length = 5.17
    spots = nf.blind_spots(system)
    assert len(spots) == 1
    assert spots[0].area == pytest.approx(length**2 / 4.0, rel=1e-6)
    assert spots[0].centroid.x == pytest.approx(-1.13 + length / 2.0, abs=1e-6)
    grid = nf.grid_blind_spots(system, 0.05)
    assert grid.area == pytest.approx(length**2 / 4.0, rel=0.02)


def test_rectangular_hole_between_three_half_planes_and_the_body(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # a sensor on a pole 2 m beside the body: a geometric construction, not a vehicle
    # (vehicle files refuse mounts farther than MOUNT_TOLERANCE_M from the body)
    monkeypatch.setattr(vehicle_config, "MOUNT_TOLERANCE_M", 3.0)
    system = _vehicle_with(
        tmp_path,
        [
            {"id": "front", "x": 4.04, "y": 0.975, "yaw": 0.0, "hfov": 180.0, "range": 20.0},
            {"id": "rear", "x": -1.13, "y": 0.975, "yaw": 180.0, "hfov": 180.0, "range": 20.0},
            {"id": "pole", "x": 1.455, "y": 2.975, "yaw": 90.0, "hfov": 180.0, "range": 20.0},
        ],
    )
    spots = nf.blind_spots(system)
    assert len(spots) == 1
    assert spots[0].area == pytest.approx(5.17 * 2.0, rel=1e-6)
    assert spots[0].bounds == pytest.approx((-1.13, 0.975, 4.04, 2.975), abs=1e-6)
    assert nf.grid_blind_spots(system, 0.05).area == pytest.approx(10.34, rel=0.02)
    # a hole reaching beyond the near-field window is not a near-field blind spot
    assert nf.blind_spots(system, radius=1.0) == []


def test_unseen_area_open_to_the_outside_is_reported(tmp_path: Path) -> None:
    """A vehicle with one forward-looking sensor has no *enclosed* blind spot (the paper's
    measure), yet everything behind its front bumper is seen by no sensor. By hand: System
    A's body x -1.13..4.04, |y| <= 0.975; window = body grown by 5 m; the sensor at the
    front bumper with a 180 deg field of view sees x >= 4.04 (its sector's arc, 20 m, lies
    beyond the window). Unseen = 10.17 m x 11.95 m - 5.17 m x 1.95 m = 111.45 m2."""
    system = _vehicle_with(
        tmp_path,
        [{"id": "front", "x": 4.04, "y": 0.0, "yaw": 0.0, "hfov": 180.0, "range": 20.0}],
    )
    assert nf.blind_spots(system) == []
    unseen = nf.unseen_at_any_height(system)
    assert unseen.area == pytest.approx(10.17 * 11.95 - 5.17 * 1.95, rel=1e-6)
    assert unseen.bounds == pytest.approx((-6.13, -5.975, 4.04, 5.975), abs=1e-6)
    summary = nf.write_nearfield(system, tmp_path / "nf", resolution=0.2, dphi_deg=0.5)
    block = summary["unseen_any_height_m2"]
    assert block["enclosed"] == summary["blind_spot_m2"]["exact"] == 0.0
    assert block["open_to_outside"] == block["exact"] == pytest.approx(111.45, abs=1e-5)


# ----------------------------------------------------------------------- presets


@pytest.fixture(scope="module")
def exact() -> dict[str, dict[str, float]]:
    out: dict[str, dict[str, float]] = {}
    for key in ("A", "B"):
        system = load_system(f"system_{key.lower()}")
        out[key] = {
            "blind": sum(p.area for p in nf.blind_spots(system)),
            "uncovered": nf.uncovered_at_height(system, 0.1).area,
        }
    return out


def test_preset_blind_spots_match_the_paper(exact: dict[str, dict[str, float]]) -> None:
    assert exact["B"]["blind"] < exact["A"]["blind"]
    for key, paper in PAPER_BLIND_SPOT_M2.items():
        got = exact[key]["blind"]
        assert math.isfinite(got) and got >= 0.0
        assert abs(got - paper) <= NEARFIELD_TOLERANCE * paper, (key, got, paper)
        assert exact[key]["uncovered"] >= got  # blind at all heights -> blind at 0.1 m


@pytest.mark.parametrize("key", ["A", "B"])
def test_grid_converges_to_exact(key: str, exact: dict[str, dict[str, float]]) -> None:
    system = load_system(f"system_{key.lower()}")
    err_blind = [
        abs(nf.grid_blind_spots(system, r).area - exact[key]["blind"]) for r in (0.2, 0.05)
    ]
    err_unc = [
        abs(nf.grid_uncovered_at_height(system, 0.1, r).area - exact[key]["uncovered"])
        for r in (0.2, 0.05)
    ]
    assert err_blind[1] < err_blind[0] and err_blind[1] < 0.1
    assert err_unc[1] < err_unc[0] and err_unc[1] < 0.1


def test_write_nearfield_is_deterministic(tmp_path: Path, system_b: System) -> None:
    runs = []
    for name in ("one", "two"):
        nf.clear_memo()  # two computations
        summary = nf.write_nearfield(system_b, tmp_path / name, resolution=0.2, dphi_deg=0.5)
        runs.append(
            {f: (tmp_path / name / f).read_bytes() for f in ("nearfield.json", "nearfield.png")}
        )
    assert runs[0] == runs[1]
    assert runs[0]["nearfield.png"].startswith(b"\x89PNG")
    data = json.loads(runs[0]["nearfield.json"])
    assert data == json.loads(json.dumps(summary))
    assert data["system"] == "System B"
    for key in ("blind_spot_m2", "uncovered_0p1m_m2"):
        block = data[key]
        for f in ("exact", "grid"):
            assert math.isfinite(block[f]) and block[f] >= 0.0
        assert block["resolution_m"] == 0.2
        assert block["difference"] == pytest.approx(block["grid"] - block["exact"], abs=1e-5)
    unseen = data["unseen_any_height_m2"]  # B sees all around: only enclosed spots
    assert unseen["exact"] == pytest.approx(data["blind_spot_m2"]["exact"], abs=1e-5)
    assert unseen["open_to_outside"] == pytest.approx(0.0, abs=1e-5)
    holes = data["blind_spot_m2"]["holes"]
    assert sum(h["area_m2"] for h in holes) == pytest.approx(
        data["blind_spot_m2"]["exact"], abs=1e-5
    )
    w = data["window"]
    assert (w["xmin"], w["xmax"]) == pytest.approx((-1.05 - 5.0, 3.93 + 5.0))


def test_a_near_field_is_computed_once_per_vehicle_and_settings(
    tmp_path: Path, system_b: System, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The near-field memo: the same vehicle and settings again give the same files
    without computing them again, and a summary the caller changes does not change the
    next one; another setting or a vehicle with one sensor moved is computed."""
    calls: list[str] = []
    blind = nf.grid_blind_spots

    def counted(system: System, *args: object, **kw: object) -> object:
        calls.append(system.name)
        return blind(system, *args, **kw)  # type: ignore[arg-type]

    monkeypatch.setattr(nf, "grid_blind_spots", counted)
    nf.clear_memo()
    first = nf.write_nearfield(system_b, tmp_path / "a", resolution=0.2, dphi_deg=0.5)
    first["blind_spot_m2"]["exact"] = -1.0  # the caller's copy
    again = nf.write_nearfield(system_b, tmp_path / "b", resolution=0.2, dphi_deg=0.5)
    assert len(calls) == 1 and again["blind_spot_m2"]["exact"] >= 0.0
    for f in ("nearfield.json", "nearfield.png"):
        assert (tmp_path / "a" / f).read_bytes() == (tmp_path / "b" / f).read_bytes()
    nf.write_nearfield(system_b, tmp_path / "c", resolution=0.25, dphi_deg=0.5)
    assert len(calls) == 2
    s0 = system_b.sensors[0]
    moved = replace(
        system_b,
        sensors=(replace(s0, mount=replace(s0.mount, x=s0.mount.x + 0.1)),) + system_b.sensors[1:],
    )
    nf.write_nearfield(moved, tmp_path / "d", resolution=0.2, dphi_deg=0.5)
    assert len(calls) == 3
    nf.clear_memo()


def test_nearfield_legend_covers_nothing(system_b: System) -> None:
    # issue #14 item 6: the legend sits below the plot, not over blind spots or sensors
    win = nf.near_field_window(system_b)
    fps = nf.any_height_footprints(system_b, dphi_deg=1.0)
    spots = nf.blind_spots(system_b, footprints=fps)
    unc = nf.uncovered_at_height(system_b, dphi_deg=1.0)
    fig = nf.nearfield_figure(system_b, win, fps, spots, unc, nf.MIN_OBJECT_HEIGHT_M)
    fig.canvas.draw()
    ax = fig.axes[0]
    assert not ax.get_legend() and len(fig.legends) == 1
    texts = [t.get_text() for t in fig.legends[0].get_texts()]
    assert "blind spot (no sensor, any height)" in texts
    assert not fig.legends[0].get_window_extent().overlaps(ax.get_window_extent())
