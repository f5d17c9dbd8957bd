"""Evaluate a scenario: target in the ego frame per step, Pd per step, criticality.

Two modes (``Evaluator(mode=...)``):

* ``exact``: ``evaluate_points`` at every step, with the sun resolved for the ego heading
  of the step (headings grouped to 0.1 deg for a world-frame sun).
* ``lookup``: per (weather, target class) one per-sensor coverage map without sun
  (``evaluate_grid(per_sensor=True)``, 0.5 m cells over x -120..260 m, y -40..40 m at the
  target's reference height), bilinear interpolation of each sensor's Pd, fused with eq. 11.
  Cameras that the sun can glare at a step (``may_be_glared``; sun direction per ego
  heading, 1 deg bins) and points outside the map are evaluated exactly, so the lookup only
  approximates the interpolation between cell centres (error measured in
  ``benchmarks/bench_search.py``).
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass, field
from functools import cached_property
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from sensorgap.config import EnvironmentConfig, TargetConfig, load_target
from sensorgap.coverage import GridSpec, Scene, evaluate_grid, evaluate_points
from sensorgap.coverage.kernel import evaluate_sensor
from sensorgap.errors import InputError
from sensorgap.models import Conditions, System
from sensorgap.scenarios.family import Scenario
from sensorgap.scenarios.trajectory import DT_S

F64 = NDArray[np.float64]

#: Lateral margin added to the half widths for "in the ego's path", m.
LATERAL_MARGIN_M = 0.2
#: Map extent (vehicle frame, m) and cell size of the lookup maps.
MAP_EXTENT = (-120.0, 260.0, -40.0, 40.0)
MAP_RESOLUTION_M = 0.5
_ALMOST_ONE = float(np.nextafter(1.0, 0.0))


@dataclass(frozen=True)
class DetectionRule:
    """When a target counts as reliably detected.

    ``cumulative``: the first step at which ``1 - P_undet(t) >= threshold`` (independent
    steps). ``m_of_n``: track confirmation, the first step k at which the probability that at
    least ``m`` of the last ``n`` cycles detected the target is ``>= threshold``
    (Poisson-binomial over the window, independent cycles).
    """

    kind: Literal["cumulative", "m_of_n"] = "cumulative"
    m: int = 3
    n: int = 5
    threshold: float = 0.99

    @classmethod
    def parse(cls, text: str) -> DetectionRule:
        """``cumulative`` or ``M/N`` (e.g. ``3/5``); anything else -> ``InputError``."""
        if text == "cumulative":
            return cls()
        parts = text.split("/")
        if len(parts) == 2 and all(p.strip().isdigit() for p in parts):
            m, n = int(parts[0]), int(parts[1])
            if 1 <= m <= n <= 50:
                return cls(kind="m_of_n", m=m, n=n)
        raise InputError("--detection", "", f"expected 'cumulative' or M/N with "
                         f"1 <= M <= N <= 50 (e.g. 3/5), got {text!r}")

    def label(self) -> str:
        """Short text for settings and reports."""
        return "cumulative" if self.kind == "cumulative" else f"{self.m}/{self.n}"


@dataclass
class Trace:
    """Per-step quantities of one evaluated scenario (truncated at a collision).

    Attributes:
        t: time, s. x, y: target centre in the ego vehicle frame, m. pd: fused Pd.
        ttc: time to collision, s (inf: not in path or not closing; 0: overlapping).
        headway: time headway to an in-path target ahead, s (inf otherwise).
        distance: ego rear axle to target centre, m. ego_speed: m/s.
        heading: ego heading, rad (world). collided: the scenario ended in a collision.
    """

    t: F64
    x: F64
    y: F64
    pd: F64
    ttc: F64
    headway: F64
    distance: F64
    ego_speed: F64
    heading: F64
    collided: bool
    duration_s: float
    extra: dict[str, float] = field(default_factory=dict)
    rule: DetectionRule = field(default_factory=DetectionRule)

    @cached_property
    def log_undetected(self) -> F64:
        """log P(not detected in any step up to and including k) (independent steps)."""
        return np.cumsum(np.log1p(-np.minimum(self.pd, _ALMOST_ONE)))

    @cached_property
    def p_undetected(self) -> F64:
        """P_undet(t_k) = prod_{j<=k} (1 - Pd_j)."""
        return np.exp(self.log_undetected)


@dataclass(frozen=True)
class Kinematics:
    """Ego-frame target position and criticality per step (before truncation)."""

    x: F64
    y: F64
    ttc: F64
    headway: F64
    distance: F64


def kinematics(sc: Scenario, system: System, target: TargetConfig) -> Kinematics:
    """Target position in the ego frame, TTC (longitudinal, in-path only), headway."""
    body = system.config.vehicle
    e, g = sc.ego, sc.target
    c, s = np.cos(e.heading), np.sin(e.heading)
    dx, dy = g.x - e.x, g.y - e.y
    xr, yr = c * dx + s * dy, -s * dx + c * dy
    vxe, vye = e.velocity()
    vxt, vyt = g.velocity()
    vxr = c * (vxt - vxe) + s * (vyt - vye)
    dh = g.heading - e.heading
    ac, as_ = np.abs(np.cos(dh)), np.abs(np.sin(dh))
    half_long = 0.5 * (ac * target.length_m + as_ * target.width_m)
    half_lat = 0.5 * (as_ * target.length_m + ac * target.width_m)
    in_path = np.abs(yr) <= 0.5 * body.width_m + half_lat + LATERAL_MARGIN_M
    front = xr >= 0.5 * (body.x_front_m + body.x_rear_m)
    gap = np.where(front, xr - half_long - body.x_front_m, body.x_rear_m - xr - half_long)
    closing = np.where(front, -vxr, vxr)
    ttc = np.full_like(xr, np.inf)
    hit = in_path & (gap <= 0.0)
    ttc[hit] = 0.0
    closing_ok = in_path & ~hit & (closing > 1e-9)
    ttc[closing_ok] = gap[closing_ok] / closing[closing_ok]
    headway = np.full_like(xr, np.inf)
    ahead = in_path & front & ~hit & (e.speed > 0.1)
    headway[ahead] = gap[ahead] / e.speed[ahead]
    return Kinematics(xr, yr, ttc, headway, np.hypot(xr, yr))


def _env_weather_key(env: EnvironmentConfig) -> str:
    return env.model_dump_json(exclude={"sun", "description", "sources"})


class Evaluator:
    """Pd per step for scenarios of one vehicle (caches scenes and coverage maps)."""

    def __init__(self, system: System, mode: str = "lookup", max_maps: int = 32,
                 resolution_m: float = MAP_RESOLUTION_M,
                 rule: DetectionRule | None = None) -> None:
        if mode not in ("lookup", "exact"):
            raise ValueError(f"mode must be 'lookup' or 'exact', got {mode!r}")
        self.system = system
        self.mode = mode
        self.rule = rule or DetectionRule()
        self.resolution_m = resolution_m
        self.max_maps = max_maps
        self._maps: OrderedDict[tuple[str, str], tuple[GridSpec, NDArray[np.float32]]] = (
            OrderedDict())
        self._scenes: OrderedDict[tuple[object, ...], Scene] = OrderedDict()
        self._targets: dict[str, TargetConfig] = {}
        self.sensor_ids = system.sensor_ids()

    # -- caches ------------------------------------------------------------------------
    def target(self, name: str) -> TargetConfig:
        """A target class by name (cached)."""
        if name not in self._targets:
            self._targets[name] = load_target(name)
        return self._targets[name]

    def _sun(self, env: EnvironmentConfig, heading: float,
             bin_deg: float) -> tuple[tuple[object, ...], Conditions]:
        """(cache key, conditions) for ``env`` at an ego heading; sun quantised."""
        wkey = _env_weather_key(env)
        cond = Conditions.from_config(env, heading)
        sun = env.sun
        if cond.sun_direction is None or sun is None:
            return (wkey, None), cond
        if sun.frame == "world":
            az_v = math.degrees(0.5 * math.pi - sun.azimuth_rad - heading)
            az_v = (round(az_v / bin_deg) * bin_deg) % 360.0
        else:
            az_v = sun.azimuth_deg % 360.0
        el = math.radians(sun.elevation_deg)
        a = math.radians(az_v)
        direction = (math.cos(el) * math.cos(a), math.cos(el) * math.sin(a), math.sin(el))
        key = (wkey, round(az_v, 6), sun.elevation_deg, sun.direct_irradiance_w_m2)
        return key, Conditions(env=env, sun_direction=direction)

    def scene(self, key: tuple[object, ...], target: TargetConfig, cond: Conditions) -> Scene:
        """A cached scene for (conditions key, target)."""
        k = (*key, target.name)
        sc = self._scenes.get(k)
        if sc is None:
            sc = Scene(self.system, target, cond)
            self._scenes[k] = sc
            if len(self._scenes) > 512:
                self._scenes.popitem(last=False)
        else:
            self._scenes.move_to_end(k)
        return sc

    def _map(self, env: EnvironmentConfig, target: TargetConfig
             ) -> tuple[GridSpec, NDArray[np.float32]]:
        key = (_env_weather_key(env), target.name)
        hit = self._maps.get(key)
        if hit is not None:
            self._maps.move_to_end(key)
            return hit
        grid = GridSpec(*MAP_EXTENT, self.resolution_m, target.reference_height_m)
        scene = Scene(self.system, target, Conditions(env=env, sun_direction=None))
        cov = evaluate_grid(scene, grid, per_sensor=True)
        stack = np.zeros((len(self.sensor_ids), grid.ny, grid.nx), dtype=np.float32)
        for i, sid in enumerate(self.sensor_ids):
            if sid in cov.pd:
                stack[i] = cov.pd[sid]
        self._maps[key] = (grid, stack)
        if len(self._maps) > self.max_maps:
            self._maps.popitem(last=False)
        return grid, stack

    # -- evaluation --------------------------------------------------------------------
    def per_sensor_pd(self, env: EnvironmentConfig, target: TargetConfig, heading: F64,
                      x: F64, y: F64, exact: bool | None = None) -> F64:
        """(S, N) per-sensor Pd at vehicle-frame points x, y (m) for ego headings (rad)."""
        exact = self.mode == "exact" if exact is None else exact
        n = len(x)
        out = np.zeros((len(self.sensor_ids), n))
        z = np.full(n, target.reference_height_m)
        bin_deg = 0.1 if exact else 1.0
        # group the steps by their (quantised) sun key
        if env.sun is not None and env.sun.frame == "world":
            hq = np.round(np.degrees(heading) / bin_deg).astype(np.int64)
            groups = [(int(h) * bin_deg, np.flatnonzero(hq == h)) for h in np.unique(hq)]
        else:
            groups = [(0.0, np.arange(n))]
        inside = np.zeros(n, dtype=bool)
        if not exact:
            grid, stack = self._map(env, target)
            xs0, ys0 = grid.xmin + 0.5 * grid.resolution, grid.ymin + 0.5 * grid.resolution
            fx, fy = (x - xs0) / grid.resolution, (y - ys0) / grid.resolution
            inside = (fx >= 0.0) & (fx <= grid.nx - 1) & (fy >= 0.0) & (fy <= grid.ny - 1)
            idx = np.flatnonzero(inside)
            if idx.size:
                i0 = np.minimum(fx[idx].astype(np.int64), grid.nx - 2)
                j0 = np.minimum(fy[idx].astype(np.int64), grid.ny - 2)
                ax, ay = fx[idx] - i0, fy[idx] - j0
                p00, p01 = stack[:, j0, i0], stack[:, j0, i0 + 1]
                p10, p11 = stack[:, j0 + 1, i0], stack[:, j0 + 1, i0 + 1]
                out[:, idx] = ((1 - ay) * ((1 - ax) * p00 + ax * p01)
                               + ay * ((1 - ax) * p10 + ax * p11))
        for h_deg, steps in groups:
            key, cond = self._sun(env, math.radians(h_deg), bin_deg)
            scene = self.scene(key, target, cond)
            if exact:
                cov = evaluate_points(scene, np.column_stack([x[steps], y[steps], z[steps]]))
                out[:, steps] = cov.pd
                continue
            outside = steps[~inside[steps]]
            if outside.size:
                cov = evaluate_points(scene, np.column_stack([x[outside], y[outside],
                                                              z[outside]]))
                out[:, outside] = cov.pd
            lookup = steps[inside[steps]]
            if lookup.size == 0 or cond.sun_direction is None:
                continue
            for row, s in enumerate(self.system.sensors):
                if s.model.may_be_glared(s.mount, cond):
                    ix, _, pd = evaluate_sensor(scene, s, x[lookup], y[lookup], z[lookup])
                    out[row, lookup] = 0.0
                    out[row, lookup[ix]] = pd
        return out

    def fused_pd(self, env: EnvironmentConfig, target: TargetConfig, heading: F64,
                 x: F64, y: F64) -> F64:
        """Fused Pd (eq. 11) at the points."""
        ps = np.clip(self.per_sensor_pd(env, target, heading, x, y), 0.0, 1.0)
        certain = np.any(ps >= 1.0, axis=0)
        fused = -np.expm1(np.sum(np.log1p(-np.minimum(ps, _ALMOST_ONE)), axis=0))
        fused[certain] = 1.0
        return np.asarray(fused + 0.0, dtype=np.float64)

    def trace(self, sc: Scenario, env: EnvironmentConfig, duration_s: float) -> Trace:
        """Evaluate a generated scenario in ``env``."""
        target = self.target(sc.target_class)
        kin = kinematics(sc, self.system, target)
        hits = np.flatnonzero(kin.ttc <= 0.0)
        n = int(hits[0]) + 1 if hits.size else len(kin.x)
        pd = self.fused_pd(env, target, sc.ego.heading[:n], kin.x[:n], kin.y[:n])
        return Trace(t=sc.ego.t[:n], x=kin.x[:n], y=kin.y[:n], pd=pd, ttc=kin.ttc[:n],
                     headway=kin.headway[:n], distance=kin.distance[:n],
                     ego_speed=sc.ego.speed[:n], heading=sc.ego.heading[:n],
                     collided=bool(hits.size), duration_s=duration_s, rule=self.rule)


__all__ = ["DT_S", "Evaluator", "Kinematics", "Trace", "kinematics"]
