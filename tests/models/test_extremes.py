"""Numerical extremes: ranges 0 .. 1e5 m, 340 dB/km fog, every target, sun at every
elevation: finite outputs, Pd in [0, 1], no warnings (RuntimeWarnings are errors here and
numpy floating-point errors raise, see conftest)."""

from __future__ import annotations

import numpy as np
import pytest

from sensorgap.config import EnvironmentConfig, load_target
from sensorgap.config.environment import SunConfig
from sensorgap.coverage import Scene, evaluate_points
from sensorgap.models import Conditions, System
from sensorgap.models.numerics import SNR_CEIL_DB, SNR_FLOOR_DB

RANGES = np.array([0.0, 1e-9, 1e-6, 1e-3, 0.1, 1.0, 10.0, 100.0, 1e3, 1e4, 1e5])


def scene(system: System, target: str, **env: object) -> Scene:
    e = EnvironmentConfig(name="x", **env)  # type: ignore[arg-type]
    return Scene(system, load_target(target), Conditions.from_config(e))


@pytest.mark.parametrize("target", ["pedestrian", "bike", "car", "truck"])
@pytest.mark.parametrize(
    "env",
    [
        {},
        {"visibility_m": 50.0},  # ~340 dB/km in every optical band
        {"rain_mm_h": 400.0, "snow_mm_h": 100.0, "visibility_m": 1.0},
        {"irradiance_w_m2": 0.0},
        {"sun": SunConfig(azimuth_deg=0.0, elevation_deg=0.001)},
    ],
)
def test_every_sensor_finite_at_every_range(
    system_a: System, system_b: System, target: str, env: dict[str, object]
) -> None:
    for system in (system_a, system_b):
        sc = scene(system, target, **env)
        for s in system.sensors:
            m = s.mount
            d = np.array([np.cos(m.yaw), np.sin(m.yaw)])
            pts = np.column_stack(
                [m.x + RANGES * d[0], m.y + RANGES * d[1], np.full_like(RANGES, m.z)]
            )
            cov = evaluate_points(sc, pts)
            assert np.all(np.isfinite(cov.snr_db)) and np.all(np.isfinite(cov.pd))
            assert np.all((cov.snr_db >= SNR_FLOOR_DB) & (cov.snr_db <= SNR_CEIL_DB))
            assert np.all((cov.pd >= 0.0) & (cov.pd <= 1.0))
            assert np.all((cov.fused >= 0.0) & (cov.fused <= 1.0))
            row = cov.sensor_ids.index(s.id)
            assert cov.pd[row, 0] == 0.0  # r = 0: the aperture itself is never "seen"


@pytest.mark.parametrize("elevation", np.linspace(-90.0, 90.0, 13).tolist())
def test_sun_elevation_sweep(system_b: System, elevation: float) -> None:
    sc = scene(system_b, "car", sun=SunConfig(azimuth_deg=-20.0, elevation_deg=elevation))
    pts = np.column_stack([np.linspace(1, 300, 50), np.zeros(50), np.full(50, 0.75)])
    cov = evaluate_points(sc, pts)
    assert np.all(np.isfinite(cov.pd)) and np.all((cov.fused >= 0) & (cov.fused <= 1))
    if elevation <= 0.0:
        assert not any(": glare:" in e for e in sc.log["effects"])
