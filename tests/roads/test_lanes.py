"""Lane widths, borders and centre lines against hand-computed offsets."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest

from sensorgap.errors import InputError
from sensorgap.roads import RoadNetwork

from .builders import document, road_xml

W = 3.75  # motorway lane width, m


def test_motorway_constant_widths_and_edges(motorway: RoadNetwork) -> None:
    s = np.array([0.0, 250.0, 550.0, 1000.0, motorway.road(1).length])
    for lane, (inner, outer) in {
        -1: (0.0, -W),
        -2: (-W, -2 * W),
        1: (0.0, W),
        2: (W, 2 * W),
    }.items():
        np.testing.assert_allclose(motorway.lane_width(1, lane, s), W, atol=1e-12)
        ti, to = motorway.lane_edges(1, lane, s)
        np.testing.assert_allclose(ti, inner, atol=1e-12)
        np.testing.assert_allclose(to, outer, atol=1e-12)


def test_motorway_lane_centres_on_the_straight(motorway: RoadNetwork) -> None:
    s = np.linspace(0.0, 500.0, 11)
    for lane, t in {-1: -1.875, -2: -5.625, 1: 1.875, 2: 5.625}.items():
        x, y, h, k = motorway.lane_center(1, lane, s)
        np.testing.assert_allclose(x, s, atol=1e-12)
        np.testing.assert_allclose(y, t, atol=1e-12)
        np.testing.assert_allclose(h, 0.0, atol=1e-15)
        np.testing.assert_allclose(k, 0.0, atol=1e-15)


def test_motorway_lane_centres_on_the_arc(motorway: RoadNetwork) -> None:
    arc = motorway.road(1).geometries[2]
    r = 500.0
    cx, cy = arc.x - r * math.sin(arc.hdg), arc.y + r * math.cos(arc.hdg)  # curve turns left
    s = np.linspace(arc.s, arc.s + arc.length, 9)
    _, _, h_ref = motorway.reference_line(1, s)
    for lane, t in {-1: -1.875, -2: -5.625, 1: 1.875, 2: 5.625}.items():
        x, y, h, k = motorway.lane_center(1, lane, s)
        # concentric circles: radius R - t, curvature 1 / (R - t), heading unchanged (1e-9)
        np.testing.assert_allclose(np.hypot(x - cx, y - cy), r - t, atol=1e-9)
        np.testing.assert_allclose(k, 1.0 / (r - t), rtol=1e-12)
        np.testing.assert_allclose(h, h_ref, atol=1e-12)


# Straight road along +x, 100 m, two lane sections (0-50 m, 50-100 m) and a laneOffset.
# laneOffset: 0.2 + 0.001 s up to s = 60, then 0.26 (continuous).
# Section 0: lane 1 polynomial width (two records), lane 2 2.0 m; lane -1 3.5 m, lane -2 widens
# from 0 to 3 m with zero slope at both ends: w = 3 (3 q^2 - 2 q^3), q = ds / 50.
# Section 1: lane 1 3.0 m; lanes -1 3.5 m and -2 3.0 m.
W1 = (3.0, 0.01, -1e-4, 1e-6)  # lane 1 record 0 (sOffset 0)
W1B = (3.1, 0.0, 2e-4, 0.0)  # lane 1 record 1 (sOffset 25), ds from 25
WIDEN = (0.0, 0.0, 9.0 / 50**2, -6.0 / 50**3)


def _width_xml(s_off: float, co: tuple[float, float, float, float]) -> str:
    a, b, c, d = co
    return f'<width sOffset="{s_off}" a="{a!r}" b="{b!r}" c="{c!r}" d="{d!r}"/>'


def _lane(lane_id: int, *widths: str) -> str:
    return f'<lane id="{lane_id}" type="driving">{"".join(widths)}</lane>'


POLY_DOC = document(
    road_xml(
        lanes=(
            '<lanes><laneOffset s="0" a="0.2" b="0.001" c="0" d="0"/>'
            '<laneOffset s="60" a="0.26" b="0" c="0" d="0"/>'
            '<laneSection s="0"><left>'
            + _lane(1, _width_xml(0, W1), _width_xml(25, W1B))
            + _lane(2, _width_xml(0, (2, 0, 0, 0)))
            + '</left><center><lane id="0" type="none"/></center><right>'
            + _lane(-1, _width_xml(0, (3.5, 0, 0, 0)))
            + _lane(-2, _width_xml(0, WIDEN))
            + '</right></laneSection><laneSection s="50"><left>'
            + _lane(1, _width_xml(0, (3.0, 0, 0, 0)))
            + '</left><center><lane id="0" type="none"/></center><right>'
            + _lane(-1, _width_xml(0, (3.5, 0, 0, 0)))
            + _lane(-2, _width_xml(0, (3.0, 0, 0, 0)))
            + "</right></laneSection></lanes>"
        )
    )
)


def _poly(co: tuple[float, ...], u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    a, b, c, d = co
    return a + b * u + c * u**2 + d * u**3, b + 2 * c * u + 3 * d * u**2, 2 * c + 6 * d * u


@pytest.fixture
def poly(load_xodr: Callable[..., RoadNetwork]) -> RoadNetwork:
    return load_xodr(POLY_DOC)


def test_polynomial_widths_by_hand(poly: RoadNetwork) -> None:
    s = np.array([0.0, 10.0, 24.9, 25.0, 40.0, 49.99])
    w_expect = np.where(s < 25.0, _poly(W1, s)[0], _poly(W1B, s - 25.0)[0])
    np.testing.assert_allclose(poly.lane_width(1, 1, s), w_expect, atol=1e-12)
    np.testing.assert_allclose(poly.lane_width(1, -2, s), _poly(WIDEN, s)[0], atol=1e-12)
    assert poly.lane_width(1, -2, np.array([25.0]))[0] == pytest.approx(1.5, abs=1e-12)
    # section 1 (s >= 50): constant widths
    np.testing.assert_allclose(poly.lane_width(1, -2, np.array([50.0, 99.0])), 3.0, atol=0)
    np.testing.assert_allclose(poly.lane_width(1, 1, np.array([50.0, 100.0])), 3.0, atol=0)


def test_polynomial_lane_centre_offsets_by_hand(poly: RoadNetwork) -> None:
    s = np.linspace(0.0, 49.0, 8)
    off, doff = 0.2 + 0.001 * s, 0.001
    w, dw, ddw = _poly(WIDEN, s)
    t = off - (3.5 + 0.5 * w)  # lane -2 centre: offset - (width of -1 + half its own)
    dt, ddt = doff - 0.5 * dw, -0.5 * ddw
    x, y, h, k = poly.lane_center(1, -2, s)
    np.testing.assert_allclose(x, s, atol=1e-12)
    np.testing.assert_allclose(y, t, atol=1e-12)
    # on a straight reference line the centre line is the graph y = t(s)
    np.testing.assert_allclose(h, np.arctan(dt), atol=1e-12)
    np.testing.assert_allclose(k, ddt / (1 + dt**2) ** 1.5, atol=1e-12)
    # lane 2 (left, outer): offset + width of lane 1 + 1.0 (half of 2 m)
    w1 = np.where(s < 25.0, _poly(W1, s)[0], _poly(W1B, s - 25.0)[0])
    np.testing.assert_allclose(poly.lane_center(1, 2, s)[1], off + w1 + 1.0, atol=1e-12)
    # lane 0 is the laneOffset line; the offset switches records at s = 60
    s2 = np.array([55.0, 60.0, 80.0])
    np.testing.assert_allclose(poly.lane_center(1, 0, s2)[1], [0.255, 0.26, 0.26], atol=1e-12)
    np.testing.assert_allclose(
        poly.lane_center(1, -1, s2)[1], np.array([0.255, 0.26, 0.26]) - 1.75, atol=1e-12
    )


def test_lanes_existing_per_section(poly: RoadNetwork) -> None:
    assert poly.lane_exists(1, 2) and poly.lane_exists("1", 2, s=10.0)
    assert not poly.lane_exists(1, 2, s=70.0)
    assert not poly.lane_exists(1, 3) and not poly.lane_exists(1, 0)
    assert not poly.lane_exists(2, -1)  # no road 2
    with pytest.raises(
        InputError,
        match=r"test\.xodr: road\[id=1\]/lane\[id=2\]: lane does not "
        r"exist at s=70",
    ):
        poly.lane_center(1, 2, np.array([10.0, 70.0]))
    with pytest.raises(InputError, match=r"lane\[id=-3\]"):
        poly.lane_center(1, -3, np.array([10.0]))
    with pytest.raises(InputError, match=r"road\[id=7\]: road does not exist"):
        poly.lane_center(7, -1, np.array([10.0]))
    with pytest.raises(InputError, match=r"s must be within \[0, 100\] m"):
        poly.lane_center(1, -1, np.array([100.5]))
    with pytest.raises(InputError, match=r"s must be within"):
        poly.reference_line(1, float("nan"))


def test_lane_at_borders(poly: RoadNetwork) -> None:
    # at s = 60: offset 0.26; left lane 1 [0.26, 3.26), right lane -1 (-3.24, 0.26], -2 beyond
    s = np.full(7, 60.0)
    t = np.array([0.26, 1.0, 3.26, 0.26 - 1e-9, -3.24, -6.23, -6.25])
    np.testing.assert_array_equal(poly.lane_at(1, s, t), [1, 1, 0, -1, -2, -2, 0])


def test_lane_centre_heading_and_curvature_on_a_clothoid_with_varying_offsets(
    load_xodr: Callable[..., RoadNetwork],
) -> None:
    # curvature changes (clothoid) while the lane offset and width change: every term of the
    # offset-curve formulas is active; compare with finite differences of the centre line
    geo = (
        '<geometry s="0" x="0" y="0" hdg="0.3" length="100"><spiral curvStart="0.001" '
        'curvEnd="0.03"/></geometry>'
    )
    lanes = (
        '<lanes><laneOffset s="0" a="0.1" b="0.01" c="-2e-4" d="1e-6"/>'
        '<laneSection s="0"><center><lane id="0" type="none"/></center><right>'
        + _lane(-1, _width_xml(0, (3.0, 0.02, 1e-4, -1e-6)))
        + _lane(-2, _width_xml(0, (2.0, -0.01, 3e-4, 0.0)))
        + "</right></laneSection></lanes>"
    )
    net = load_xodr(document(road_xml(geometry=geo, lanes=lanes)))
    s = np.linspace(5.0, 95.0, 10)
    e = 1e-4
    for lane in (-1, -2):
        x, y, h, k = net.lane_center(1, lane, s)
        xp, yp, hp, _ = net.lane_center(1, lane, s + e)
        xm, ym, hm, _ = net.lane_center(1, lane, s - e)
        np.testing.assert_allclose(h, np.arctan2(yp - ym, xp - xm), atol=1e-8)
        np.testing.assert_allclose(k, (hp - hm) / np.hypot(xp - xm, yp - ym), rtol=1e-6)
        assert np.all(np.abs(k) > 1e-3)  # the check is not trivially on a straight line


def test_no_lane_offset_before_the_first_lane_offset_record(
    load_xodr: Callable[..., RoadNetwork],
) -> None:
    """OpenDRIVE shifts the centre lane from each laneOffset record on; before the first one
    there is no shift (it was extrapolated backwards: 0.1 * (30 - 60) = -3 m at s 30). By
    hand, lane -1 (3.5 m) on a straight road along +x: centre y = -1.75 up to s 60, then
    0.1 (s - 60) - 1.75: 0.25 at s 80; heading 0 before 60, atan(0.1) after."""
    net = load_xodr(
        document(
            road_xml().replace("<lanes>", '<lanes><laneOffset s="60" a="0" b="0.1" c="0" d="0"/>')
        )
    )
    x, y, h, _ = net.lane_center(1, -1, np.array([0.0, 30.0, 59.0, 80.0, 100.0]))
    np.testing.assert_allclose(y, [-1.75, -1.75, -1.75, 0.25, 2.25], atol=1e-12)
    np.testing.assert_allclose(h, [0.0, 0.0, 0.0, math.atan(0.1), math.atan(0.1)], atol=1e-12)
    left, right = net.road_extents(1, np.array([30.0, 80.0]))
    np.testing.assert_allclose(left, [3.5, 5.5], atol=1e-12)
    np.testing.assert_allclose(right, [-3.5, -1.5], atol=1e-12)
