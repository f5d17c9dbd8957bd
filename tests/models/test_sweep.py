"""Numerical sweep (issue #8): every sensor of both presets, every target class, range
1e-6 .. 1e5 m, specific attenuation 0 .. 400 dB/km, sun elevation -90 .. 90 deg: finite
SNR and Pd in [0, 1]; Pd non-increasing with range (from 1 m, along the boresight), with
attenuation and with glare, as the physics says."""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import pytest

from sensorgap.config import EnvironmentConfig, load_target, load_targets
from sensorgap.config.environment import SunConfig
from sensorgap.coverage import Scene, evaluate_points
from sensorgap.models import Conditions, System, load_system
from sensorgap.models.conditions import Band
from sensorgap.models.numerics import SNR_CEIL_DB, SNR_FLOOR_DB

RANGES = np.logspace(-6, 5, 67)
GAMMAS = np.linspace(0.0, 400.0, 9)
TARGETS = list(load_targets())
SYSTEMS = {name: load_system(name) for name in ("system_a", "system_b")}


@dataclass
class FixedAttenuation(Conditions):
    """Conditions with one specific attenuation (dB/km) in every band."""

    gamma_db_km: float = 0.0

    def attenuation_db_km(self, band: Band) -> float:
        return self.gamma_db_km


def _boresight(system: System, sensor_id: str, r: np.ndarray) -> np.ndarray:
    s = next(x for x in system.sensors if x.id == sensor_id)
    m = s.mount
    d = np.array(
        [np.cos(m.pitch) * np.cos(m.yaw), np.cos(m.pitch) * np.sin(m.yaw), -np.sin(m.pitch)]
    )
    return np.column_stack([m.x + r * d[0], m.y + r * d[1], m.z + r * d[2]])


def _sensor_pd(scene: Scene, sensor_id: str, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    cov = evaluate_points(scene, pts, cull=False)
    row = cov.sensor_ids.index(sensor_id)
    return cov.snr_db[row], cov.pd[row]


@pytest.mark.parametrize("system_name", list(SYSTEMS))
@pytest.mark.parametrize("target", TARGETS)
def test_range_sweep_finite_bounded_monotone(system_name: str, target: str) -> None:
    system = SYSTEMS[system_name]
    scene = Scene(
        system, load_target(target), Conditions.from_config(EnvironmentConfig(name="clear"))
    )
    for s in system.sensors:
        snr, pd = _sensor_pd(scene, s.id, _boresight(system, s.id, RANGES))
        assert np.all(np.isfinite(snr)) and np.all(np.isfinite(pd))
        assert np.all((snr >= SNR_FLOOR_DB) & (snr <= SNR_CEIL_DB))
        assert np.all((pd >= 0.0) & (pd <= 1.0))
        lo = max(1.0, s.mount.min_range)
        far = np.greater_equal(RANGES, lo)
        assert np.all(np.diff(pd[far]) <= 1e-12), f"{s.id}: Pd rises with range"


@pytest.mark.parametrize("system_name", list(SYSTEMS))
def test_attenuation_sweep_monotone(system_name: str) -> None:
    system = SYSTEMS[system_name]
    env = EnvironmentConfig(name="x")
    for target in TARGETS:
        pds = []
        for g in GAMMAS:
            scene = Scene(
                system,
                load_target(target),
                FixedAttenuation(env=env, sun_direction=None, gamma_db_km=float(g)),
            )
            cov = evaluate_points(
                scene,
                np.vstack(
                    [_boresight(system, s.id, np.array([2.0, 20.0, 80.0])) for s in system.sensors]
                ),
                cull=False,
            )
            assert np.all(np.isfinite(cov.pd)) and np.all((cov.pd >= 0) & (cov.pd <= 1))
            pds.append(cov.pd)
        stack = np.array(pds)  # (gamma, sensor, point)
        assert np.all(np.diff(stack, axis=0) <= 1e-12), f"{target}: Pd rises with attenuation"
        assert np.all(stack[-1] <= stack[0])


@functools.cache
def _dark_pd(system_name: str, target: str, sensor_id: str) -> np.ndarray:
    """Pd of one sensor without sun at ``_boresight`` points 1, 10, 50, 150 m: the same for
    every sun elevation, computed once per module (read-only)."""
    system = SYSTEMS[system_name]
    dark = Scene(system, load_target(target), Conditions.from_config(EnvironmentConfig(name="x")))
    pts = _boresight(system, sensor_id, np.array([1.0, 10.0, 50.0, 150.0]))
    pd = _sensor_pd(dark, sensor_id, pts)[1]
    pd.flags.writeable = False
    return pd


@pytest.mark.parametrize("elevation", np.linspace(-90.0, 90.0, 19).tolist())
def test_sun_elevation_sweep_glare_never_helps(elevation: float) -> None:
    reduced = 0
    for system_name, system in SYSTEMS.items():
        for target in TARGETS:
            tgt = load_target(target)
            for s in system.sensors:
                if s.type_name != "camera":
                    continue
                m = s.mount
                env = EnvironmentConfig(
                    name="sun",
                    sun=SunConfig(
                        azimuth_deg=float(np.degrees(m.yaw)),
                        elevation_deg=elevation,
                        direct_irradiance_w_m2=900.0,
                    ),
                )
                sunny = Scene(system, tgt, Conditions.from_config(env))
                pts = _boresight(system, s.id, np.array([1.0, 10.0, 50.0, 150.0]))
                _, pd_sun = _sensor_pd(sunny, s.id, pts)
                pd_dark = _dark_pd(system_name, target, s.id)
                assert np.all(np.isfinite(pd_sun)) and np.all((pd_sun >= 0) & (pd_sun <= 1))
                assert np.all(pd_sun <= pd_dark + 1e-12), f"{s.id}: glare raised Pd"
                reduced += int(np.any(pd_sun < pd_dark - 1e-6))
    if 0.0 < elevation <= 30.0:  # a low sun straight into the cameras must blind some
        assert reduced > 0
    if elevation <= 0.0:  # no sun below the horizon
        assert reduced == 0
