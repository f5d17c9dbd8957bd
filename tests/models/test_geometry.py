"""Sensor frames and fields of view: trig-free FOV test vs the angle definition, yaw wrap,
FOV 0 and 360 deg, pitch sign."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from sensorgap.models.geometry import (
    Mount,
    fov_mask,
    horizontal_reach_bbox,
    rotate_offsets,
    spherical,
)

coord = st.floats(min_value=-200.0, max_value=200.0)


def mount(
    yaw_deg: float = 0.0, pitch_deg: float = 0.0, hfov: float = 60.0, vfov: float = 20.0
) -> Mount:
    return Mount(
        1.0,
        -0.5,
        0.6,
        math.radians(yaw_deg),
        math.radians(pitch_deg),
        math.radians(hfov),
        math.radians(vfov),
        0.0,
        300.0,
    )


@settings(max_examples=300)
@given(
    coord,
    coord,
    coord,
    st.floats(-180.0, 180.0),
    st.floats(-60.0, 60.0),
    st.floats(0.0, 360.0),
    st.floats(0.0, 180.0),
)
def test_fov_mask_matches_angle_definition(
    x: float, y: float, z: float, yaw: float, pitch: float, hfov: float, vfov: float
) -> None:
    m = mount(yaw, pitch, hfov, vfov)
    xs, ys, zs = rotate_offsets(m, np.array([x - m.x]), np.array([y - m.y]), z - m.z)
    _, az, el = spherical(xs, ys, zs)
    inside = bool(fov_mask(m, xs, ys, zs)[0])
    margin_h = abs(abs(float(az[0])) - 0.5 * m.hfov)
    margin_v = abs(abs(float(el[0])) - 0.5 * m.vfov)
    if margin_h > 1e-9 and margin_v > 1e-9 and float(np.hypot(xs, ys)[0]) > 1e-9:
        want = abs(float(az[0])) <= 0.5 * m.hfov and abs(float(el[0])) <= 0.5 * m.vfov
        assert inside == want


def test_yaw_wrap_is_invisible() -> None:
    pts = np.random.default_rng(1).uniform(-50, 50, size=(3, 500))
    a = mount(179.0)
    b = mount(-181.0)
    ra = rotate_offsets(a, pts[0], pts[1], 0.3)
    rb = rotate_offsets(b, pts[0], pts[1], 0.3)
    for u, v in zip(ra, rb, strict=True):
        np.testing.assert_allclose(u, v, atol=1e-12)
    np.testing.assert_array_equal(fov_mask(a, *ra), fov_mask(b, *rb))


def test_fov_360_sees_everything_fov_0_only_boresight() -> None:
    full = mount(hfov=360.0, vfov=180.0)
    xs = np.array([1.0, -1.0, 0.0, 0.0])
    ys = np.array([0.0, 0.0, 1.0, -1.0])
    zs = np.array([5.0, -5.0, 0.0, 0.0])
    assert fov_mask(full, xs, ys, zs).all()
    zero = mount(hfov=0.0, vfov=0.0)
    got = fov_mask(
        zero, np.array([10.0, 10.0, 10.0]), np.array([0.0, 1e-6, 0.0]), np.array([0.0, 0.0, 1e-6])
    )
    assert got.tolist() == [True, False, False]


def test_positive_pitch_looks_down() -> None:
    m = mount(pitch_deg=30.0)
    # a point below the boresight in the vehicle frame is on the sensor's x axis
    xs, ys, zs = rotate_offsets(
        m, np.array([math.cos(math.radians(30))]), np.array([0.0]), -math.sin(math.radians(30))
    )
    assert abs(float(zs[0])) < 1e-12 and abs(float(ys[0])) < 1e-12 and float(xs[0]) > 0.99


def test_reach_bbox_contains_fov_points() -> None:
    rng = np.random.default_rng(7)
    for yaw in (-170.0, -45.0, 0.0, 90.0, 135.0):
        m = mount(yaw, hfov=100.0, vfov=180.0)
        bb = horizontal_reach_bbox(m, 0.75)
        assert bb is not None
        x = rng.uniform(-400, 400, 20000)
        y = rng.uniform(-400, 400, 20000)
        xs, ys, zs = rotate_offsets(m, x - m.x, y - m.y, 0.75 - m.z)
        r = np.sqrt(xs**2 + ys**2 + zs**2)
        vis = fov_mask(m, xs, ys, zs) & (r <= m.max_range)
        assert np.all((x[vis] >= bb[0]) & (x[vis] <= bb[1]) & (y[vis] >= bb[2]) & (y[vis] <= bb[3]))
