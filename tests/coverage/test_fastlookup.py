"""The compiled lookup along tracks (``fastlookup.lookup_pass`` via
``logmiss.lookup_log_miss_tracks``) equals the point-wise lookup (``lookup_log_miss``) and
its glare weights equal ``Camera.glare_weights``."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sensorgap.config import EnvironmentConfig, SunConfig, load_environments, load_target
from sensorgap.coverage import GridSpec, Scene
from sensorgap.coverage.fastlookup import (
    SUN_NONE,
    SUN_VEHICLE,
    SUN_WORLD,
    cone_cos_bound,
    glare_cone_weight,
    sun_directions_at,
    sun_directions_of,
)
from sensorgap.coverage.logmiss import LogMissMaps, lookup_log_miss, lookup_log_miss_tracks
from sensorgap.models import Conditions, load_system
from sensorgap.models.camera import Camera
from sensorgap.models.geometry import Mount

ENVS = load_environments()


@pytest.mark.parametrize("pitch_deg", [0.0, 20.0, 70.0])
@pytest.mark.parametrize("margin_deg", [0.0, 10.0])
def test_glare_cone_weight_equals_camera_glare_weights(pitch_deg: float, margin_deg: float) -> None:
    system = load_system("system_a")
    cam = next(s for s in system.sensors if isinstance(s.model, Camera))
    model = cam.model
    assert isinstance(model, Camera)
    model = Camera(model.params.model_copy(update={"glare_margin_deg": margin_deg}))
    mount = Mount(
        0.0,
        0.0,
        1.5,
        math.radians(30.0),
        math.radians(pitch_deg),
        math.radians(120.0),
        math.radians(60.0),
        0.1,
        100.0,
    )
    rng = np.random.default_rng(7)
    az = rng.uniform(-math.pi, math.pi, 4000)
    el = np.arcsin(rng.uniform(-1.0, 1.0, 4000))  # uniform on the sphere
    d = np.column_stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    want = model.glare_weights(mount, d)
    cone = model.glare_cone(mount)
    bound = cone_cos_bound(cone.half_h, cone.half_v, cone.margin)
    got = np.array(
        [
            glare_cone_weight(*v, cone.rotation, cone.half_h, cone.half_v, cone.margin, bound)
            for v in d
        ]
    )
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
    assert 0 < np.count_nonzero(want == 1.0) < want.size  # inside and outside both hit
    if margin_deg:
        assert np.count_nonzero((want > 0) & (want < 1)) > 10  # the fade is exercised


@pytest.mark.parametrize("system_name", ["system_a", "system_b"])
def test_tracks_lookup_equals_point_lookup(system_name: str) -> None:
    """Rows with a world-frame sun over turning headings, a vehicle-frame sun and none;
    points inside and outside the map; level and pitched cameras (System A's fisheyes);
    absolute agreement 1e-9 (the sensor azimuth of a level camera is computed as a
    difference of angles instead of through atan2: a rounding difference)."""
    env = ENVS["clear"]
    system = load_system(system_name)
    car = load_target("car")
    scene = Scene(system, car, Conditions(env=env, sun_direction=None))
    grid = GridSpec(-40.0, 90.0, -20.0, 20.0, 0.5, car.reference_height_m)
    maps = LogMissMaps.build(scene, grid)
    rng = np.random.default_rng(5)
    b, t = 36, 41
    x = rng.uniform(-50.0, 100.0, (b, t))  # some beyond the map: exact there
    y = rng.uniform(-25.0, 25.0, (b, t))
    heading = rng.uniform(-math.pi, math.pi, (b, 1)) + np.linspace(0.0, 0.8, t)[None, :]
    sun = np.zeros((b, 3))
    sun[:, 0] = np.resize([SUN_WORLD, SUN_VEHICLE, SUN_NONE], b)
    sun[:, 1] = rng.uniform(0.0, 2 * math.pi, b)
    sun[:, 2] = rng.uniform(math.radians(2.0), math.radians(40.0), b)
    n = rng.integers(1, t + 1, b).astype(np.int64)
    rows = np.arange(0, b, dtype=np.int64)[::-1].copy()  # any order, every row
    out = np.full((b, t), 123.0)
    lookup_log_miss_tracks(maps, scene, x, y, heading, n, rows, sun, out)
    for r in range(b):
        k = n[r]
        dirs = sun_directions_of(np.repeat(sun[r : r + 1], k, axis=0), heading[r, :k])
        want, _ = lookup_log_miss(
            maps,
            scene,
            x[r, :k],
            y[r, :k],
            np.full(k, car.reference_height_m),
            None if sun[r, 0] == SUN_NONE else dirs,
        )
        np.testing.assert_allclose(out[r, :k], want, rtol=0, atol=1e-9)
        assert np.all(out[r, k:] == 123.0)  # steps beyond n are not written
    assert np.all(np.isfinite(out))


def test_sun_rows_match_the_preset_and_searched_suns() -> None:
    """The per-row sun of the evaluator gives the directions of ``Conditions``."""
    from sensorgap.search.evaluate import _sun_directions, _sun_rows

    heading = np.linspace(-3.0, 3.0, 9)
    for name in ("clear", "glare_front_right", "fog_50", "night"):
        if name not in ENVS:
            continue
        env = ENVS[name]
        sun_deg = np.full((9, 2), np.nan)
        sun_deg[::2] = [[120.0, 15.0]] * 5
        sun_deg[1] = [40.0, -3.0]  # below the horizon: no direct sun
        rows = _sun_rows(env, sun_deg)
        want = _sun_directions(env, sun_deg, heading)
        got = sun_directions_of(rows, heading)
        if want is None:
            assert np.all(rows[:, 0] == SUN_NONE)
        else:
            np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)


def _sun_by_hand(kind: float, az: float, el: float, heading: float) -> np.ndarray:
    """The vehicle-frame sun unit vector written out (not the kernel's angle sum): a
    vehicle-frame sun at azimuth ``az`` (counter-clockwise from x) and elevation ``el``;
    a world-frame sun at compass azimuth ``az`` (clockwise from north): its east-north-up
    vector, then rotated by minus the ego ``heading`` (counter-clockwise from east); NaN
    for no sun."""
    if kind == SUN_NONE:
        return np.full(3, np.nan)
    ce, se = math.cos(el), math.sin(el)
    if kind == SUN_VEHICLE:
        return np.array([ce * math.cos(az), ce * math.sin(az), se])
    east, north = ce * math.sin(az), ce * math.cos(az)
    ch, sh = math.cos(heading), math.sin(heading)
    return np.array([ch * east + sh * north, -sh * east + ch * north, se])


def test_sun_directions_equal_the_rotation_by_hand() -> None:
    """``_sun_directions`` (``sun_directions_of``, ``sun_directions_at``) against the
    world sun rotated into the vehicle frame by hand (``_sun_by_hand``) and the numpy
    ``Conditions.sun_directions``: compass azimuths all round, elevations 0 (horizon:
    the kernel gets it only when a caller passes it; it has no cut-off), 90 deg and
    between, headings wrapping past +-pi (up to +-3 pi, as unwrapped track headings),
    vehicle-frame suns (heading ignored) and no sun (NaN). Tolerance atol 4e-15: the
    kernel rounds the angle sum pi/2 - azimuth - heading (|a| < 14 rad here, ulp
    1.8e-15; measured 8.3e-16)."""
    az = np.radians(np.arange(0.0, 360.0, 22.5))
    el = np.radians([0.0, 0.5, 15.0, 45.0, 89.0, 90.0])
    heading = np.array(
        [0.0, 0.7, -2.0, math.pi, -math.pi, math.pi + 0.1, -math.pi - 0.1, 3.0 * math.pi, -8.0]
    )
    a, e, h = (g.ravel() for g in np.meshgrid(az, el, heading, indexing="ij"))
    n = a.size
    kind = np.resize([SUN_WORLD, SUN_WORLD, SUN_VEHICLE, SUN_NONE], n).astype(float)
    sun = np.column_stack([kind, a, e])
    got = sun_directions_of(sun, h)
    want = np.array([_sun_by_hand(*sun[i], h[i]) for i in range(n)])
    none = kind == SUN_NONE
    assert np.all(np.isnan(got[none])) and not np.any(np.isnan(got[~none]))
    np.testing.assert_allclose(got[~none], want[~none], rtol=0, atol=4e-15)
    np.testing.assert_allclose(np.linalg.norm(got[~none], axis=1), 1.0, rtol=0, atol=4e-15)
    # a few directions written down: heading 0 (east), sun due north on the horizon: to
    # the left; heading pi/2 (north): straight ahead; heading -pi/2 (south), sun due east:
    # to the left; the zenith is straight up whatever the heading; pi + 0.1 = -pi + 0.1
    rows = np.array(
        [
            [SUN_WORLD, 0.0, 0.0],
            [SUN_WORLD, 0.0, 0.0],
            [SUN_WORLD, 0.5 * math.pi, 0.0],
            [SUN_WORLD, 1.0, 0.5 * math.pi],
            [SUN_VEHICLE, -0.5 * math.pi, 0.0],
        ]
    )
    got = sun_directions_of(rows, np.array([0.0, 0.5 * math.pi, -0.5 * math.pi, 2.5, 1.0]))
    want = [[0, 1, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0, -1, 0]]
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-15)
    wrap = sun_directions_of(
        np.array([[SUN_WORLD, 2.0, 0.3]] * 2), np.array([math.pi + 0.1, -math.pi + 0.1])
    )
    np.testing.assert_allclose(wrap[0], wrap[1], rtol=0, atol=4e-15)
    # the numpy ``Conditions.sun_directions`` (elevation > 0 only: None at the horizon)
    for frame in ("world", "vehicle"):
        for el_deg in (0.5, 30.0, 90.0):
            env = EnvironmentConfig(
                name="clear", sun=SunConfig(azimuth_deg=250.0, elevation_deg=el_deg, frame=frame)
            )
            want = Conditions.sun_directions(env, heading)
            assert want is not None
            k = SUN_WORLD if frame == "world" else SUN_VEHICLE
            row = [k, math.radians(250.0), math.radians(el_deg)]
            got = sun_directions_of(np.array([row] * heading.size), heading)
            np.testing.assert_allclose(got, want, rtol=0, atol=4e-15)
    env0 = EnvironmentConfig(name="clear", sun=SunConfig(azimuth_deg=250.0, elevation_deg=0.0))
    assert Conditions.sun_directions(env0, heading) is None


def test_sun_directions_at_take_the_row_of_each_flat_index() -> None:
    """``sun_directions_at``: flat index m of (B, T) tracks takes the sun of row m // T
    and the heading at m (three rows, one per kind, picked in any order)."""
    t = 4
    sun = np.array([[SUN_WORLD, 1.2, 0.4], [SUN_NONE, 0.0, 0.0], [SUN_VEHICLE, -0.7, 0.2]])
    heading = np.linspace(-3.5, 3.5, 3 * t).reshape(3, t)
    flat = np.array([11, 0, 5, 3, 8, 4, 9], dtype=np.int64)
    got = sun_directions_at(sun, heading, flat, t)
    for m, f in enumerate(flat):
        want = _sun_by_hand(*sun[f // t], heading.ravel()[f])
        if f // t == 1:
            assert np.all(np.isnan(got[m]))
        else:
            np.testing.assert_allclose(got[m], want, rtol=0, atol=4e-15)


@pytest.fixture(scope="module")
def cam_main_maps() -> tuple[LogMissMaps, GridSpec, int]:
    """System B's lookup maps for a car in clear air on a 110 x 40 m grid, and the row of
    its main camera."""
    system = load_system("system_b")
    car = load_target("car")
    scene = Scene(system, car, Conditions(env=ENVS["clear"], sun_direction=None))
    grid = GridSpec(-20.0, 90.0, -20.0, 20.0, 0.5, car.reference_height_m)
    return LogMissMaps.build(scene, grid), grid, system.sensor_ids().index("cam_main")


def test_a_cameras_part_of_the_body_maps_is_removed_exactly(
    cam_main_maps: tuple[LogMissMaps, GridSpec, int],
) -> None:
    """A glared camera's no-sun part is subtracted from the interpolated body total and
    its glared value added. The part subtracted (``_outline_layer``) must be what
    ``LogMissMaps.body_totals`` put in: re-interpolating the layer at the outline points
    instead differed by up to 33 nepers where detection is near certain (a glared camera
    left at Pd 0.97 where exact evaluation gave 0.006). Here: a one-camera body map
    interpolated at random centres and headings equals ``_outline_layer`` there (float32
    rounding), for the min and a higher order statistic."""
    from sensorgap.coverage.logmiss import TrackLookup, _outline_layer

    maps, grid, row = cam_main_maps
    outline = np.array(
        [[x, y] for x in (-0.9, 0.0, 1.2, 3.9) for y in (-0.9, 0.9)] + [[-0.9, 0.0], [3.9, 0.0]]
    )
    rng = np.random.default_rng(3)
    b, t = 4, 60
    xf = rng.uniform(-10.0, 85.0, b * t)
    yf = rng.uniform(-15.0, 15.0, b * t)
    psi = rng.uniform(-math.pi, math.pi, (b, t))
    gi = np.arange(b * t, dtype=np.int64)
    for q in (0, 3):
        totals = maps.body_totals(outline, (row,), 12, (q,))
        how = TrackLookup(
            totals,
            psi,
            frozenset({row}),
            lambda f: np.zeros(f.size),
            lambda r, f: np.zeros(f.size),
            outline,
            {row: q},
        )
        h = np.rint(np.mod(psi.reshape(-1), math.pi) / (math.pi / 12)).astype(int) % 12
        want = np.array([_bilinear_at(totals[h[k]], grid, xf[k], yf[k]) for k in range(b * t)])
        got = _outline_layer(maps, row, gi, xf, yf, how)
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-4)
        assert np.min(want) < -10.0  # near-certain detections are among the points


def test_a_body_layer_is_the_order_statistic_over_the_rotated_outline(
    cam_main_maps: tuple[LogMissMaps, GridSpec, int],
) -> None:
    """``LogMissMaps.body_layer`` (which the body totals sum and the glared lookup takes
    out again): at random cells and heading bins, the q-th smallest of the sensor's layer
    over the outline rotated by the bin's angle and rounded to whole cells, 0 off the map,
    by hand; the crop holds every non-zero value."""
    maps, grid, row = cam_main_maps
    layer = maps.layers[row]
    ny, nx = layer.shape
    outline = np.array([[x, y] for x in (-0.9, 1.2, 3.9) for y in (-0.9, 0.9)] + [[3.9, 0.0]])
    rng = np.random.default_rng(5)
    for q in (0, 2):
        part = maps.body_layer(outline, row, 12, q)
        assert part is not None
        full = np.zeros((12, ny, nx), dtype=np.float32)
        cy, cx = part.values.shape[1:]
        full[:, part.j0 : part.j0 + cy, part.i0 : part.i0 + cx] = part.values
        checked = 0
        for _ in range(400):
            h, j, i = int(rng.integers(12)), int(rng.integers(ny)), int(rng.integers(nx))
            a = h * math.pi / 12
            vals = []
            for ox, oy in outline:
                di = round((math.cos(a) * ox - math.sin(a) * oy) / grid.resolution)
                dj = round((math.sin(a) * ox + math.cos(a) * oy) / grid.resolution)
                inside = 0 <= j + dj < ny and 0 <= i + di < nx
                vals.append(float(layer[j + dj, i + di]) if inside else 0.0)
            want = sorted(vals)[q]
            assert full[h, j, i] == pytest.approx(want, abs=0.0), (h, j, i)
            checked += want < -1.0
        assert checked > 20  # cells in the camera's view are among them


def _bilinear_at(img: np.ndarray, grid: GridSpec, x: float, y: float) -> float:
    """Bilinear value of a map at one vehicle-frame point, by hand."""
    fx = (x - (grid.xmin + 0.5 * grid.resolution)) / grid.resolution
    fy = (y - (grid.ymin + 0.5 * grid.resolution)) / grid.resolution
    ny, nx = img.shape
    i, j = min(int(fx), nx - 2), min(int(fy), ny - 2)
    ax, ay = fx - i, fy - j
    return float(
        (1 - ay) * ((1 - ax) * img[j, i] + ax * img[j, i + 1])
        + ay * ((1 - ax) * img[j + 1, i] + ax * img[j + 1, i + 1])
    )


def test_near_view_mask_is_a_box_dilation() -> None:
    """A cell is near the view when some cell within ``reach`` cells (a square) is in
    view: by hand for one in-view cell and at the map's border."""
    from sensorgap.coverage.fastlookup import near_view_mask

    sig = np.full((2, 7, 9), np.nan, dtype=np.float32)
    sig[0, 3, 4] = 1.0
    sig[1, 0, 0] = 2.0
    m = near_view_mask(sig, 2)
    want0 = np.zeros((7, 9), dtype=bool)
    want0[1:6, 2:7] = True
    want1 = np.zeros((7, 9), dtype=bool)
    want1[0:3, 0:3] = True
    assert np.array_equal(m[0], want0) and np.array_equal(m[1], want1)
    assert np.array_equal(near_view_mask(sig, 0), np.isfinite(sig))
