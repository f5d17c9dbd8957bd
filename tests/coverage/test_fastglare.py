"""The compiled glare lookup (``fastglare``) equals its numpy reference: the camera's own
``snr_from_signal``, ``glare_factors`` and ROC (``logmiss._glared_values_numpy``)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sensorgap.config import load_environments, load_target
from sensorgap.config.vehicle import RocConfig
from sensorgap.coverage import GridSpec, Scene
from sensorgap.coverage.fastglare import roc_log_miss
from sensorgap.coverage.fastkernel import roc_constants
from sensorgap.coverage.kernel import evaluate_offsets
from sensorgap.coverage.logmiss import (
    GlaredBodies,
    LogMissMaps,
    _glare_at,
    _glared_values,
    _glared_values_numpy,
    log_miss_of,
)
from sensorgap.models import Conditions, load_system
from sensorgap.models.geometry import rotate_offsets, spherical
from sensorgap.models.numerics import clip_snr_db
from sensorgap.models.roc import detection_probability
from sensorgap.models.system import Sensor

ENVS = load_environments()


def _same_log_miss(got: np.ndarray, want: np.ndarray) -> None:
    """ln(1 - Pd) values agree: Pd to 1e-13 absolute, and ln(1 - Pd) to 1e-9 relative
    where 1 - Pd > 1e-5. (Closer to Pd = 1 the reference's ``log1p(-Pd)`` amplifies one
    ulp of Pd, from ``exp`` in numpy's vectorised libm against the scalar one, up to the
    cap: ln(2^-52) = -36.04 against ln(2^-53) = -36.74, both "certain".)"""
    np.testing.assert_allclose(-np.expm1(got), -np.expm1(want), rtol=0.0, atol=1e-13)
    far = want > math.log(1e-5)
    np.testing.assert_allclose(got[far], want[far], rtol=1e-9, atol=1e-15)


@pytest.mark.parametrize(
    "roc",
    [
        RocConfig(kind="paper", snr50_db=10.0, floor_db=7.5),
        RocConfig(kind="smoothstep", snr50_db=10.0, half_width_db=12.0),
        RocConfig(kind="swerling1", pfa=1e-6),
    ],
)
@pytest.mark.parametrize("shift_db", [0.0, 3.0])
def test_roc_log_miss_equals_the_numpy_roc(roc: RocConfig, shift_db: float) -> None:
    """Over SNRs from -400 to 400 dB (beyond the clip at +-300), including the floor and
    the ends of the smoothstep: the same Pd (see ``_same_log_miss``)."""
    snr = np.concatenate([np.linspace(-400.0, 400.0, 20_001), [-300.0, 300.0, 7.5, 10.5]])
    consts = roc_constants(roc, shift_db)
    assert consts is not None
    want = log_miss_of(detection_probability(clip_snr_db(snr.copy()), roc, shift_db))
    got = np.array([roc_log_miss(float(v), consts[0], consts[1]) for v in snr])
    _same_log_miss(got, want)
    assert np.any(want > -1e-5) and np.any(want < -30.0)  # both ends of the curve hit


def _exact_at(
    scene: Scene, s: Sensor, bodies: GlaredBodies, outline: np.ndarray, flat: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """ln(1 - Pd) of camera ``s`` at outline points ``flat`` of the (M * K) points of
    ``bodies`` in numpy, with the bodies' own glare weights: the camera's field of view and
    range (``evaluate_offsets``), ``snr_db_glare`` at its range and angles with the factor
    of ``glare_factors``, and the ROC. Also whether each point is in view."""
    k = len(outline)
    b, o = flat // k, flat % k
    c, sn = np.cos(bodies.psi[b]), np.sin(bodies.psi[b])
    px = bodies.x[b] + c * outline[o, 0] - sn * outline[o, 1]
    py = bodies.y[b] + sn * outline[o, 0] + c * outline[o, 1]
    m = s.mount
    dx, dy, dz = px - m.x, py - m.y, bodies.z[b] - m.z
    ok, _, _ = evaluate_offsets(scene, s, dx, dy, dz)
    vals = np.zeros(flat.size)
    if ok.any():
        r, az, el = spherical(*rotate_offsets(m, dx[ok], dy[ok], dz[ok]))
        fac, _ = _glare_at(
            s, px[ok], py[ok], bodies.z[b][ok], bodies.sun_dirs[b][ok], bodies.weights[b][ok]
        )
        prepared = scene.prepared(s)
        assert prepared.snr_db_glare is not None
        snr = clip_snr_db(prepared.snr_db_glare(r, az, el, fac))
        vals[ok] = log_miss_of(detection_probability(snr, s.roc, scene.roc_shift_db))
    return vals, ok


@pytest.mark.parametrize("env_name", ["clear", "glare_front_right"])
def test_compiled_glare_equals_the_numpy_reference(env_name: str) -> None:
    """System B's glare-prone cameras in a scene with a sun, bodies of a car at random
    headings and places (in, at the edge of and out of view), random vehicle-frame sun
    directions (some near each camera's boresight) and glare weights: the same states and
    Pd (see ``_same_log_miss``), at the centres and over the outline. Where the reference
    leaves a point to exact evaluation (state 2: the edge of the view, off the map), the
    compiled pass evaluates it exactly itself (state 3, or 0 out of view): equal to the
    camera's numpy model at the point (``_exact_at``)."""
    env = ENVS[env_name]
    system = load_system("system_b")
    car = load_target("car")
    scene = Scene(system, car, Conditions(env=env, sun_direction=None))
    grid = GridSpec(-30.0, 120.0, -25.0, 25.0, 0.5, car.reference_height_m)
    maps = LogMissMaps.build(scene, grid)
    rows = [r for r in maps.signal if scene.prepared(scene.sensors[r]).veil_constants is not None]
    assert rows  # the built-in camera has compiled constants
    rng = np.random.default_rng(11)
    n = 3000
    outline = np.array([[2.2, 0.9], [2.2, -0.9], [-2.2, 0.9], [-2.2, -0.9], [0.0, 0.9], [2.2, 0.0]])
    seen_glare = 0
    for row in rows:
        s = scene.sensors[row]
        x = rng.uniform(-25.0, 115.0, n)
        y = rng.uniform(-20.0, 20.0, n)
        psi = rng.uniform(-math.pi, math.pi, n)
        # half the suns near the camera's boresight (strong glare), half anywhere
        yaw = s.mount.yaw + rng.normal(0.0, 0.3, n)
        el = np.abs(rng.normal(0.0, 0.2, n))
        anywhere = rng.random(n) < 0.5
        yaw[anywhere] = rng.uniform(-math.pi, math.pi, int(anywhere.sum()))
        sun = np.column_stack([np.cos(el) * np.cos(yaw), np.cos(el) * np.sin(yaw), np.sin(el)])
        w = np.where(rng.random(n) < 0.1, 0.0, rng.uniform(0.0, 1.0, n))
        z = np.full(n, car.reference_height_m)
        bodies = GlaredBodies(x, y, psi, z, sun, w)
        for shape in (np.zeros((1, 2)), outline):
            got, st = _glared_values(maps, scene, row, bodies, shape)
            want, st_want = _glared_values_numpy(maps, scene, row, bodies, shape)
            edge = st_want == 2
            np.testing.assert_array_equal(st[~edge], st_want[~edge])
            _same_log_miss(got[~edge], want[~edge])
            exact, in_view = _exact_at(scene, s, bodies, shape, np.flatnonzero(edge.ravel()))
            np.testing.assert_array_equal(st[edge], np.where(in_view, 3, 0))
            _same_log_miss(got[edge], exact)
            assert set(np.unique(st_want)) == {0, 1, 2}  # in, out and at the edge of view
            assert 3 in st and int(np.count_nonzero(st[edge] == 0)) > 0
            seen_glare += int(np.count_nonzero((st == 3) & (got > -30.0) & (got < -1e-6)))
            seen_glare += int(np.count_nonzero((st == 1) & (want > -30.0) & (want < -1e-6)))
    assert seen_glare > 100  # the steep part of the ROC under glare is exercised
