"""The tiled, culled, threaded grid equals a straightforward per-point evaluation."""

from __future__ import annotations

import numpy as np
import pytest

from sensorgap.coverage import GridSpec, evaluate_grid, evaluate_points
from sensorgap.models import System
from tests.conftest import make_scene


@pytest.mark.parametrize("env", ["clear", "glare_front_right", "fog_50"])
@pytest.mark.parametrize("target", ["car", "pedestrian"])
def test_grid_equals_unculled_points(
    system_a: System, system_b: System, env: str, target: str
) -> None:
    grid = GridSpec(-30.0, 90.0, -20.0, 20.0, 0.7, 0.75)
    X, Y = np.meshgrid(grid.xs(), grid.ys())
    pts = np.column_stack([X.ravel(), Y.ravel(), np.full(X.size, 0.75)])
    for system in (system_a, system_b):
        scene = make_scene(system, target, env)
        fast = evaluate_grid(scene, grid, workers=2, tile_cells=997)
        ref = evaluate_points(make_scene(system, target, env), pts, cull=False)
        # saturation culling bounds the error by saturation_eps (default 1e-10)
        assert np.max(np.abs(fast.fused.ravel() - ref.fused)) <= 1e-10
        exact = evaluate_grid(make_scene(system, target, env), grid, saturation_eps=0.0)
        assert np.max(np.abs(exact.fused.ravel() - ref.fused)) <= 1e-12
        detail = evaluate_grid(make_scene(system, target, env), grid, per_sensor=True)
        # fused-only mode sums the log terms in another sensor order: 1-ulp differences
        np.testing.assert_allclose(detail.fused, exact.fused, rtol=0, atol=1e-12)
        for sid in detail.evaluated:
            row = ref.sensor_ids.index(sid)
            # numpy's SIMD log/exp may differ by 1 ulp between array lengths
            np.testing.assert_allclose(detail.pd[sid].ravel(), ref.pd[row], rtol=0, atol=1e-12)
            # SNR in dB: relative 1e-12, and 1e-12 dB absolute where it crosses 0 dB (a
            # -0.0153 dB cell differed by 1.5e-14 dB on a fresh machine: 1e-12 relative)
            np.testing.assert_allclose(
                detail.snr_db[sid].ravel(), ref.snr_db[row], rtol=1e-12, atol=1e-12
            )


def test_culled_sensors_are_not_prepared(system_a: System) -> None:
    scene = make_scene(system_a, "car", "clear")
    far = GridSpec(200.0, 240.0, -10.0, 10.0, 1.0, 0.75)
    cov = evaluate_grid(scene, far)
    assert "radar_front_center" in cov.evaluated
    assert not any(sid.startswith("us_") for sid in cov.evaluated)
    assert not any(k.startswith("us_") for k in scene._prepared)
    assert any(line.startswith("us_front_1:") for line in scene.log["skipped"])


def test_grid_spec_counts() -> None:
    g = GridSpec(-100.0, 300.0, -30.0, 30.0, 0.1, 0.75)
    assert (g.nx, g.ny, g.cells) == (4000, 600, 2_400_000)
    assert g.xs()[0] == pytest.approx(-99.95) and g.ys()[-1] == pytest.approx(29.95)
