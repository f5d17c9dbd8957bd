"""Collision outcome (``search.outcome``): hand-computed closed forms, brute force and
properties."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sensorgap.search.outcome import (
    encounter_geometry,
    first_confirmation,
    lost_distance,
    reaction_outcome,
)

DT = 0.05
T = 201
X_FRONT, X_REAR, EGO_W = 3.9, -1.1, 1.9
CAR_L, CAR_W = 4.5, 1.8


def _stopped_ahead(v0: float, gap: float, lateral: float = 0.0):
    """Ego at v0 on a straight road (x axis), a car stopped with its rear ``gap`` m ahead
    of the ego's front bumper at t = 0."""
    t = np.arange(T) * DT
    ex = (v0 * t)[None]
    z = np.zeros((1, T))
    tx = np.full((1, T), X_FRONT + gap + CAR_L / 2)
    return encounter_geometry(ex, z, z, np.full((1, T), v0), tx, z + lateral, z, z, DT,
                              (CAR_L, CAR_W), (X_FRONT, X_REAR, EGO_W), 0.5, 6.0)


def _stop_distance(v0: float, jerk: float, amax: float) -> float:
    t1 = amax / jerk
    d1 = v0 * t1 - jerk * t1 ** 3 / 6.0
    v1 = v0 - 0.5 * jerk * t1 * t1
    return d1 + v1 * v1 / (2.0 * amax)


@pytest.mark.parametrize(("v0", "gap", "lat", "mu"), [(20.0, 60.0, 0.3, 0.9),
                                                       (30.0, 120.0, 0.5, 0.6),
                                                       (13.9, 60.0, 0.2, 0.25)])
def test_t_safe_equals_the_closed_form_stopping_answer(v0, gap, lat, mu):
    # by hand: confirmed at t_c, the ego travels v0 (t_c + latency) + the jerk-limited stop
    # distance; it avoids the car while that fits in the gap. Tolerance: one 0.05 s step.
    enc = _stopped_ahead(v0, gap)
    amax = min(9.0, mu * 9.80665)
    tc = (gap - v0 * lat - _stop_distance(v0, 12.0, amax)) / v0
    o = reaction_outcome(enc, np.ones((1, T)), np.array([T]), 3, 5, lat, 12.0,
                         np.array([amax]))
    assert enc.threat_step[0] == 0
    assert tc - DT - 1e-9 <= o.t_safe_s[0] <= tc + 1e-9
    # confirmed at step 2 (3 of 5 with Pd = 1) is in time
    assert o.collision_probability[0] == 0.0
    never = reaction_outcome(enc, np.zeros((1, T)), np.array([T]), 3, 5, lat, 12.0,
                             np.array([amax]))
    assert never.collision_probability[0] == 1.0
    # never braking: impact at the full speed (the target stands)
    assert never.impact_speed_kmh[0] == pytest.approx(3.6 * v0, rel=1e-9)
    assert never.collision_perfect[0] == 0.0


def test_too_close_on_snow_is_unavoidable():
    # by hand: 13.9 m/s on snow (mu 0.25) needs 0.2 s x 13.9 + ~40 m > 40 m of gap
    enc = _stopped_ahead(13.9, 40.0)
    o = reaction_outcome(enc, np.ones((1, T)), np.array([T]), 3, 5, 0.2, 12.0,
                         np.array([0.25 * 9.80665]))
    assert math.isnan(o.t_safe_s[0])
    assert o.collision_perfect[0] == 1.0
    assert o.collision_probability[0] == 1.0


def test_lost_distance_matches_closed_form():
    v0, j, a = 25.0, 12.0, 8.0
    assert lost_distance(0.0, v0, j, a) == 0.0
    t1 = a / j
    assert lost_distance(t1, v0, j, a) == pytest.approx(j * t1 ** 3 / 6.0, rel=1e-12)
    big = 100.0
    assert lost_distance(big, v0, j, a) == pytest.approx(v0 * big - _stop_distance(v0, j, a),
                                                         rel=1e-12)


def _brute_first(pd: np.ndarray, m: int, n: int) -> np.ndarray:
    t = len(pd)
    out = np.zeros(t + 1)
    for bits in itertools.product((0, 1), repeat=t):
        p = math.prod(pd[k] if b else 1.0 - pd[k] for k, b in enumerate(bits))
        first = t
        for k in range(t):
            if sum(bits[max(0, k - n + 1):k + 1]) >= m:
                first = k
                break
        out[first] += p
    return out


@pytest.mark.parametrize(("m", "n"), [(2, 3), (3, 5), (1, 1)])
def test_first_confirmation_equals_brute_force(m, n):
    rng = np.random.default_rng(m * 10 + n)
    pd = rng.random(10)
    got = first_confirmation(pd[None], np.array([10]), m, n)[0]
    np.testing.assert_allclose(got, _brute_first(pd, m, n), rtol=0, atol=1e-13)
    assert got.sum() == pytest.approx(1.0, abs=1e-12)


def test_target_beside_the_path_is_no_threat():
    enc = _stopped_ahead(20.0, 30.0, lateral=3.75)
    o = reaction_outcome(enc, np.zeros((1, T)), np.array([T]), 3, 5, 0.3, 12.0,
                         np.array([8.0]))
    assert enc.threat_step[0] == -1
    assert o.collision_probability[0] == 0.0


@settings(max_examples=40, deadline=None)
@given(pd=st.floats(0.0, 1.0), lat1=st.floats(0.0, 1.5), extra=st.floats(0.0, 1.5),
       gap=st.floats(20.0, 100.0), v0=st.floats(8.0, 35.0))
def test_properties(pd, lat1, extra, gap, v0):
    enc = _stopped_ahead(v0, gap)
    p = np.full((1, T), pd)
    a = reaction_outcome(enc, p, np.array([T]), 3, 5, lat1, 12.0, np.array([8.0]))
    b = reaction_outcome(enc, p, np.array([T]), 3, 5, lat1 + extra, 12.0, np.array([8.0]))
    perfect = reaction_outcome(enc, np.ones((1, T)), np.array([T]), 3, 5, lat1, 12.0,
                               np.array([8.0]))
    for o in (a, b):
        assert 0.0 <= o.collision_probability[0] <= 1.0
        assert o.impact_speed_kmh[0] <= 3.6 * v0 + 1e-9  # closing speed (target stands)
    assert b.collision_probability[0] >= a.collision_probability[0] - 1e-12
    assert perfect.collision_probability[0] <= a.collision_probability[0] + 1e-12


def _sat(a: np.ndarray, b: np.ndarray) -> bool:
    """Separating-axis test of two convex polygons (4, 2)."""
    for poly in (a, b):
        for i in range(4):
            e = poly[(i + 1) % 4] - poly[i]
            n = np.array([-e[1], e[0]])
            pa, pb = a @ n, b @ n
            if pa.max() < pb.min() or pb.max() < pa.min():
                return False
    return True


def _box(x: float, y: float, h: float, front: float, rear: float, w: float) -> np.ndarray:
    c, s = math.cos(h), math.sin(h)
    pts = np.array([[front, w / 2], [front, -w / 2], [rear, -w / 2], [rear, w / 2]])
    return np.column_stack([x + c * pts[:, 0] - s * pts[:, 1], y + s * pts[:, 0] + c * pts[:, 1]])


def _brute_collides(ex, ey, eh, v0, tx, ty, th, k, kt, lat, jerk, amax) -> bool:
    """Confirmation at step k: brake at max(k, kt) dt + latency, ego on its planned path
    (pose interpolated at the braked progress), box overlap with the target at any step."""
    tb = max(k, kt) * DT + lat
    s_plan = v0 * np.arange(T) * DT
    for j in range(T):
        q = s_plan[j] - (lost_distance(j * DT - tb, v0, jerk, amax) if j * DT > tb else 0.0)
        x, y = np.interp(q, s_plan, ex), np.interp(q, s_plan, ey)
        h = np.interp(q, s_plan, eh)
        if _sat(_box(x, y, h, X_FRONT, X_REAR, EGO_W),
                _box(tx[j], ty[j], th[j], CAR_L / 2, -CAR_L / 2, CAR_W)):
            return True
    return False


@pytest.mark.parametrize("seed", range(6))
def test_interval_method_equals_brute_force_box_tests(seed: int) -> None:
    """Straight and curved (R = 300 m) ego paths, a target cutting in or stopped/slow ahead;
    for confirmation at sampled steps the kernel's collision equals a direct box-overlap
    simulation of the braked ego (one-hot Pd with 1-of-1 confirmation)."""
    rng = np.random.default_rng(seed)
    t = np.arange(T) * DT
    v0 = rng.uniform(15, 30)
    radius = [np.inf, 300.0][seed % 2]
    s = v0 * t
    if math.isinf(radius):
        ex, ey, eh = s, 0 * s, 0 * s
    else:
        ex, ey, eh = radius * np.sin(s / radius), radius * (1 - np.cos(s / radius)), s / radius
    vt = rng.uniform(0, 0.4) * v0  # closing >= 9 m/s: a collision within 10 s
    st = rng.uniform(40, 80) + vt * t
    lane = 3.5 * np.clip((t - rng.uniform(0.2, 1.0)) / 2.0, 0, 1) if seed % 3 == 0 else 0 * t
    off = 3.5 - lane if seed % 3 == 0 else 0 * t  # cut-in from the left lane
    if math.isinf(radius):
        tx, ty, th = st, off, 0 * t
    else:
        rr = radius - off
        tx, ty, th = rr * np.sin(st / radius), radius - rr * np.cos(st / radius), st / radius
    enc = encounter_geometry(ex[None], ey[None], eh[None], np.full((1, T), v0), tx[None],
                             ty[None], th[None], np.full((1, T), vt), DT, (CAR_L, CAR_W),
                             (X_FRONT, X_REAR, EGO_W), 0.5, 6.0)
    kt = int(enc.threat_step[0])
    n = int(enc.collide_step[0]) + 1 if enc.collide_step[0] >= 0 else T
    assert enc.collide_step[0] > 0 and kt >= 0
    checked = 0
    for k in sorted({0, kt, (kt + n) // 2, n - 2, n - 1}):
        if not 0 <= k < n:
            continue
        pd = np.zeros((1, T))
        pd[0, k] = 1.0
        o = reaction_outcome(enc, pd, np.array([n]), 1, 1, 0.3, 12.0, np.array([8.0]))
        want = _brute_collides(ex, ey, eh, v0, tx, ty, th, k, kt, 0.3, 12.0, 8.0)
        assert bool(o.collision_probability[0] > 0.5) == want, (k, kt, n)
        checked += 1
    assert checked >= 3
