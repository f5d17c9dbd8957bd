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
