"""Bodies where planned (issue #15 item 1): the planned boxes, the box comparison of
``simulate`` and the trajectory vertices esmini's vertex filter leaves alone (esmini runs
are in test_export.py / test_maneuver.py)."""

from __future__ import annotations

import math

import numpy as np

from sensorgap.export.bodies import PlannedBox, box_deviation, box_points
from sensorgap.export.xosc import ESMINI_TRAJ_FILTER_M, filtered_vertices
from sensorgap.scenarios.trajectory import Trajectory


def _plan(heading: float = 0.3) -> PlannedBox:
    t = np.arange(0.0, 2.0001, 0.05)
    c, s = math.cos(heading), math.sin(heading)
    return PlannedBox(
        Trajectory(
            t,
            10.0 + 8.0 * t * c,
            -3.0 + 8.0 * t * s,
            np.full_like(t, heading),
            np.full_like(t, 8.0),
        ),
        4.5,
        1.8,
    )


def test_box_corners_and_deviation() -> None:
    pts = box_points(np.array([0.0]), np.array([0.0]), np.array([math.pi / 2]), 4.0, 2.0)
    assert np.allclose(pts[0], [[0, 0], [-1, 2], [1, 2], [1, -2], [-1, -2]])
    plan = _plan()
    p = plan.centre
    h = p.heading
    ones = np.ones_like(p.t)
    # a logged origin at the rear axle 1.35 m behind the centre, box centre 1.35 m ahead
    ox, oy = p.x - 1.35 * np.cos(h), p.y - 1.35 * np.sin(h)
    dev = box_deviation(plan, p.t, ox, oy, h, 1.35 * ones, 0 * ones, 4.5 * ones, 1.8 * ones)
    assert dev < 1e-9
    # the fault issue #15 found: the box 1.35 m further ahead than planned
    dev = box_deviation(plan, p.t, ox, oy, h, 2.7 * ones, 0 * ones, 4.5 * ones, 1.8 * ones)
    assert abs(dev - 1.35) < 1e-9
    # a wrong size moves the corners: 0.2 m longer -> front corners 0.1 m off
    dev = box_deviation(plan, p.t, ox, oy, h, 1.35 * ones, 0 * ones, 4.7 * ones, 1.8 * ones)
    assert abs(dev - 0.1) < 1e-9
    # logged times after the plan's end are not compared
    assert box_deviation(plan, p.t + 10.0, ox, oy, h, ones, ones, ones, ones) == math.inf


def test_filtered_vertices_survive_the_vertex_filter_and_interpolate() -> None:
    """A target creeping at 0.036 m/s, then waiting 3 s, then starting at 1.5 m/s2, then
    braking to rest: every kept vertex is >= 0.1 m from the previous one (or the other end
    of a stand-still at the same place), and linear interpolation in time through the kept
    vertices reproduces every sample within 0.04 m (esmini's filter made the creeping
    target stand still and jump 0.1 m)."""
    t = np.arange(0.0, 10.0001, 0.05)
    x = np.where(t < 3.0, 0.036 * t, 0.036 * 3.0)
    x = np.where(t > 6.0, x + 0.75 * np.maximum(t - 6.0, 0.0) ** 2, x)
    x = np.where(t > 8.0, x[t <= 8.0][-1] + 3.0 * (t - 8.0) - 1.5 * (t - 8.0) ** 2, x)
    x = np.where(t > 9.0, x[t <= 9.0][-1], x)
    y = np.zeros_like(t)
    keep = filtered_vertices(x, y)
    assert keep[0] == 0 and keep[-1] == len(t) - 1
    d = np.hypot(np.diff(x[keep]), np.diff(y[keep]))
    inner = d[:-1]  # the last vertex is kept whatever its distance
    assert np.all((inner >= ESMINI_TRAJ_FILTER_M) | (inner == 0.0))
    assert np.any(inner == 0.0)  # the stand-still end is kept
    xi = np.interp(t, t[keep], x[keep])
    assert np.max(np.abs(xi - x)) < 0.04
    # a fast body keeps every sample
    assert filtered_vertices(20.0 * t, y) == list(range(len(t)))
