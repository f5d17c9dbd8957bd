"""Evaluate scenarios: target in the ego frame per step, Pd per step, criticality.

Batches: ``Evaluator.evaluate_batch`` takes B generated scenarios (``ScenarioBatch``) and
their environments and returns a ``BatchTrace`` of (B, T) arrays; one scenario
(``Evaluator.trace``) is a batch of one, so both agree exactly.

Pd per step, fused in the log domain (``sensorgap.coverage.logmiss``):

* ``exact``: every sensor evaluated at every step, each camera with its glare weight for
  the sun direction of that step (the ego's heading turns a world-frame sun).
* ``lookup``: per (weather, target class) per-sensor ln(1 - Pd) maps without sun (0.5 m
  cells over x -120..260 m, y -40..40 m at the target's reference height), bilinear
  interpolation; glared cameras and points outside the map are evaluated exactly, so the
  lookup only approximates the interpolation between cell centres (error measured in
  ``benchmarks/bench_search.py``).

Collisions end a scenario: steps after the first overlap of the boxes are not evaluated.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from sensorgap.config import EnvironmentConfig, TargetConfig, load_target
from sensorgap.coverage import GridSpec, Scene
from sensorgap.coverage.fastlookup import SUN_NONE, SUN_VEHICLE, SUN_WORLD, sun_directions_of
from sensorgap.coverage.logmiss import (
    ALMOST_ONE,
    LogMissMaps,
    exact_log_miss,
    log_miss_of,
    lookup_log_miss,
    lookup_log_miss_tracks,
    per_sensor_pd,
)
from sensorgap.coverage.scope import scene_scope
from sensorgap.errors import InputError
from sensorgap.models import Conditions, System
from sensorgap.scenarios.batch import ScenarioBatch, Tracks
from sensorgap.scenarios.family import Scenario
from sensorgap.scenarios.trajectory import DT_S, Trajectory
from sensorgap.search.fastkin import kinematics_kernel

F64 = NDArray[np.float64]

#: Lateral margin added to the half widths for "in the ego's path", m.
LATERAL_MARGIN_M = 0.2
#: Map extent (vehicle frame, m) and cell size of the lookup maps.
MAP_EXTENT = (-120.0, 260.0, -40.0, 40.0)
MAP_RESOLUTION_M = 0.5
_ALMOST_ONE = ALMOST_ONE


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
    log_miss: F64 | None = None

    @cached_property
    def log_undetected(self) -> F64:
        """log P(not detected in any step up to and including k) (independent steps);
        from the per-step fused ln P_miss when given (exact in the log domain), else from
        ``pd``."""
        lm = log_miss_of(self.pd) if self.log_miss is None else self.log_miss
        return np.cumsum(lm)

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


def at_least_m_of_window_batch(pd: F64, m: int, n: int) -> F64:
    """Row-wise ``at_least_m_of_window`` of a (B, T) array (same recursion per row)."""
    b, t = pd.shape
    out = np.zeros((b, t))
    for k in range(t):
        lo = max(0, k - n + 1)
        size = k + 1 - lo
        if m > size:
            continue
        dist = np.zeros((b, size + 1))
        dist[:, 0] = 1.0
        for j in range(lo, k + 1):
            p = pd[:, j:j + 1]
            dist[:, 1:] = dist[:, 1:] * (1.0 - p) + dist[:, :-1] * p
            dist[:, 0] *= 1.0 - p[:, 0]
        out[:, k] = dist[:, m:].sum(axis=1)
    return out


def kinematics_arrays(ego: Tracks | Scenario, target_tracks: Tracks | None,
                      system: System, target: TargetConfig) -> Kinematics:
    """Target position in the ego frame, TTC (longitudinal, in-path only) and headway,
    element-wise over arrays of any shape (states of ``Tracks`` or one ``Scenario``)."""
    e: Tracks | Trajectory
    g: Tracks | Trajectory
    if isinstance(ego, Scenario):
        e, g = ego.ego, ego.target
    else:
        assert target_tracks is not None
        e, g = ego, target_tracks
    body = system.config.vehicle
    shape = np.shape(e.x)

    def flat(a: F64) -> F64:
        return np.ascontiguousarray(a, dtype=np.float64).reshape(-1)

    out = [np.empty(int(np.prod(shape))) for _ in range(5)]
    kinematics_kernel(flat(e.x), flat(e.y), flat(e.heading), flat(e.speed), flat(g.x),
                      flat(g.y), flat(g.heading), flat(g.speed), target.length_m,
                      target.width_m, 0.5 * body.width_m, body.x_front_m, body.x_rear_m,
                      LATERAL_MARGIN_M, *out)
    xr, yr, ttc, headway, dist = (a.reshape(shape) for a in out)
    return Kinematics(xr, yr, ttc, headway, dist)


def kinematics(sc: Scenario, system: System, target: TargetConfig) -> Kinematics:
    """Target position in the ego frame, TTC (longitudinal, in-path only), headway."""
    return kinematics_arrays(sc, None, system, target)


@dataclass
class BatchTrace:
    """Per-step quantities of B evaluated scenarios, (B, T) arrays on one time axis.

    Row i is valid for its first ``n[i]`` steps (a collision ends a scenario); beyond that
    ``log_miss`` is 0, TTC and headway are inf and positions repeat the last valid step.
    See ``Trace`` for the meaning of each quantity.
    """

    t: F64
    x: F64
    y: F64
    log_miss: F64
    ttc: F64
    headway: F64
    distance: F64
    ego_speed: F64
    heading: F64
    n: NDArray[np.int64]
    collided: NDArray[np.bool_]
    duration_s: float
    rule: DetectionRule = field(default_factory=DetectionRule)

    def __len__(self) -> int:
        return len(self.n)

    @cached_property
    def valid(self) -> NDArray[np.bool_]:
        """(B, T) step belongs to the scenario."""
        return np.arange(len(self.t))[None, :] < self.n[:, None]

    @cached_property
    def pd(self) -> F64:
        """(B, T) fused Pd (0 beyond the valid steps)."""
        return np.asarray(-np.expm1(self.log_miss) + 0.0, dtype=np.float64)

    @cached_property
    def log_undetected(self) -> F64:
        """(B, T) ln P_undet(t_k), cumulative over the steps."""
        return np.cumsum(self.log_miss, axis=1)

    @cached_property
    def detection_index(self) -> NDArray[np.int64]:
        """(B,) first step of reliable detection under ``rule`` (-1: never); computed once
        for every metric that needs it."""
        rule = self.rule
        if rule.kind == "cumulative":
            hit = (np.exp(self.log_undetected) <= 1.0 - rule.threshold) & self.valid
        else:
            hit = (at_least_m_of_window_batch(self.pd, rule.m, rule.n) >= rule.threshold
                   ) & self.valid
        return np.asarray(np.where(hit.any(axis=1), np.argmax(hit, axis=1), -1),
                          dtype=np.int64)

    def row(self, i: int) -> Trace:
        """Scenario ``i`` as a ``Trace`` (its valid steps)."""
        k = int(self.n[i])
        return Trace(t=self.t[:k], x=self.x[i, :k], y=self.y[i, :k], pd=self.pd[i, :k],
                     ttc=self.ttc[i, :k], headway=self.headway[i, :k],
                     distance=self.distance[i, :k], ego_speed=self.ego_speed[i, :k],
                     heading=self.heading[i, :k], collided=bool(self.collided[i]),
                     duration_s=self.duration_s, rule=self.rule,
                     log_miss=self.log_miss[i, :k])


def _env_weather_key(env: EnvironmentConfig) -> str:
    return env.model_dump_json(exclude={"sun", "description", "sources"})


class Evaluator:
    """Pd per step for scenarios of one vehicle (caches scenes and lookup maps)."""

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
        self._maps: OrderedDict[tuple[str, str], LogMissMaps] = OrderedDict()
        self._scenes: dict[tuple[str, str], Scene] = {}
        self._targets: dict[str, TargetConfig] = {}
        self.sensor_ids = system.sensor_ids()
        #: point-sensor pairs evaluated exactly in lookup mode (glare, outside the map)
        self.exact_pairs = 0
        #: evaluate only the sensors that can reach a batch's region (``coverage.scope``)
        self.scoped = True
        #: sensors left out of some exact evaluation, and why
        self.scope_log: dict[str, str] = {}
        self._lock = threading.RLock()

    # -- caches ------------------------------------------------------------------------
    def target(self, name: str) -> TargetConfig:
        """A target class by name (cached)."""
        if name not in self._targets:
            self._targets[name] = load_target(name)
        return self._targets[name]

    def scene(self, env: EnvironmentConfig, target: TargetConfig) -> Scene:
        """The scene of (weather, target) without a sun direction (glare per point)."""
        key = (_env_weather_key(env), target.name)
        with self._lock:
            sc = self._scenes.get(key)
            if sc is None:
                if len(self._scenes) >= 256:
                    self._scenes.clear()
                sc = Scene(self.system, target, Conditions(env=env, sun_direction=None))
                for s in sc.sensors:  # prepared up front: scenes are shared by threads
                    sc.prepared(s)
                self._scenes[key] = sc
        return sc

    def prepare(self, env: EnvironmentConfig, target: TargetConfig) -> None:
        """Build the scene (and, in lookup mode, the maps) of (weather, target) now."""
        self.scene(env, target)
        if self.mode == "lookup":
            self.maps(env, target)

    def maps(self, env: EnvironmentConfig, target: TargetConfig) -> LogMissMaps:
        """The lookup maps of (weather, target) (cached, LRU)."""
        key = (_env_weather_key(env), target.name)
        with self._lock:
            hit = self._maps.get(key)
            if hit is not None:
                self._maps.move_to_end(key)
                return hit
            grid = GridSpec(*MAP_EXTENT, self.resolution_m, target.reference_height_m)
            maps = LogMissMaps.build(self.scene(env, target), grid, workers=2)
            self._maps[key] = maps
            if len(self._maps) > self.max_maps:
                self._maps.popitem(last=False)
            return maps

    # -- points ------------------------------------------------------------------------
    def log_miss(self, env: EnvironmentConfig, target: TargetConfig, x: F64, y: F64,
                 sun_dirs: F64 | None, exact: bool | None = None) -> F64:
        """Fused ln P_miss at vehicle-frame points (m) with per-point sun directions."""
        exact = self.mode == "exact" if exact is None else exact
        scene = self.scene(env, target)
        z = np.full(len(x), target.reference_height_m)
        if exact:
            sensors = None
            if self.scoped and len(x):
                z0 = target.reference_height_m
                scope = scene_scope(scene, np.array([x.min(), y.min(), z0]),
                                    np.array([x.max(), y.max(), z0]))
                sensors = scope.sensors
                with self._lock:
                    for sid, why in scope.skipped.items():
                        self.scope_log[sid] = why
            return exact_log_miss(scene, x, y, z, sun_dirs, sensors)
        out, n_exact = lookup_log_miss(self.maps(env, target), scene, x, y, z, sun_dirs)
        with self._lock:
            self.exact_pairs += n_exact
        return out

    def per_sensor_pd(self, env: EnvironmentConfig, target: TargetConfig, heading: F64,
                      x: F64, y: F64, exact: bool | None = None) -> F64:
        """(S, N) per-sensor Pd at vehicle-frame points x, y (m) for ego headings (rad),
        always exact (used to explain a ranked scenario)."""
        scene = self.scene(env, target)
        z = np.full(len(x), target.reference_height_m)
        return per_sensor_pd(scene, x, y, z, Conditions.sun_directions(env, heading))

    def fused_pd(self, env: EnvironmentConfig, target: TargetConfig, heading: F64,
                 x: F64, y: F64) -> F64:
        """Fused Pd (eq. 11) at the points."""
        lm = self.log_miss(env, target, x, y, Conditions.sun_directions(env, heading))
        return np.asarray(-np.expm1(lm) + 0.0, dtype=np.float64)

    # -- scenarios ---------------------------------------------------------------------
    def evaluate_batch(self, batch: ScenarioBatch, env_names: Sequence[str] | NDArray[np.str_],
                       presets: Mapping[str, EnvironmentConfig],
                       sun_deg: F64 | None = None, rows: NDArray[np.intp] | None = None,
                       duration_s: float | None = None) -> BatchTrace:
        """Evaluate the ``rows`` (default: all) of a batch.

        ``env_names[i]``: the preset of row i; ``sun_deg[i]`` (azimuth, elevation), deg:
        a world-frame sun replacing the preset's (NaN: keep the preset's sun).
        """
        target = self.target(batch.target_class)
        if rows is None or len(rows) == len(batch):
            rows = np.arange(len(batch))
            ego, tgt = batch.ego, batch.target
        else:
            ego, tgt = batch.ego.take(rows), batch.target.take(rows)
        kin = kinematics_arrays(ego, tgt, self.system, target)
        b, t = kin.x.shape
        hit = kin.ttc <= 0.0
        collided = np.asarray(hit.any(axis=1), dtype=bool)
        n = np.where(collided, np.argmax(hit, axis=1) + 1, t).astype(np.int64)
        valid = np.arange(t)[None, :] < n[:, None]
        log_miss = np.zeros((b, t))
        names = np.asarray(env_names)[rows]
        sun = (np.full((b, 2), np.nan) if sun_deg is None
               else np.asarray(sun_deg, dtype=np.float64)[rows])
        for name in np.unique(names):
            env = presets[str(name)]
            g = np.flatnonzero(names == name)
            if self.mode == "lookup":
                n_exact = lookup_log_miss_tracks(
                    self.maps(env, target), self.scene(env, target), kin.x, kin.y,
                    ego.heading, n, g, _sun_rows(env, sun), log_miss)
                with self._lock:
                    self.exact_pairs += n_exact
                continue
            vr, vc = np.nonzero(valid[g])
            gr = g[vr]
            dirs = _sun_directions(env, sun[gr], ego.heading[gr, vc])
            log_miss[gr, vc] = self.log_miss(env, target, kin.x[gr, vc], kin.y[gr, vc], dirs)
        ttc = np.where(valid, kin.ttc, np.inf)
        headway = np.where(valid, kin.headway, np.inf)
        return BatchTrace(t=batch.t, x=kin.x, y=kin.y, log_miss=log_miss, ttc=ttc,
                          headway=headway, distance=kin.distance, ego_speed=ego.speed,
                          heading=ego.heading, n=n, collided=collided,
                          duration_s=float(batch.t[-1]) if duration_s is None else duration_s,
                          rule=self.rule)

    def trace(self, sc: Scenario, env: EnvironmentConfig, duration_s: float) -> Trace:
        """Evaluate one generated scenario in ``env`` (a batch of one)."""
        batch = ScenarioBatch.of(sc)
        return self.evaluate_batch(batch, ["env"], {"env": env},
                                   duration_s=duration_s).row(0)


def _sun_rows(env: EnvironmentConfig, sun_deg: F64) -> F64:
    """(B, 3) per-row sun (kind, azimuth rad, elevation rad; ``fastlookup.SUN_*``): the
    world-frame ``sun_deg`` row where finite, else the preset's sun; none where the preset
    has no visible sun or the sun is at or below the horizon (as ``_sun_directions``)."""
    out = np.zeros((len(sun_deg), 3))
    sun = env.sun
    if sun is None or not sun.visible:
        return out
    if sun.elevation_deg > 0.0:
        out[:, 0] = SUN_WORLD if sun.frame == "world" else SUN_VEHICLE
        out[:, 1], out[:, 2] = sun.azimuth_rad, sun.elevation_rad
    override = np.isfinite(sun_deg[:, 0])
    out[override, 0] = np.where(sun_deg[override, 1] > 0.0, SUN_WORLD, SUN_NONE)
    out[override, 1] = np.radians(sun_deg[override, 0])
    out[override, 2] = np.radians(sun_deg[override, 1])
    return out


def _sun_directions(env: EnvironmentConfig, sun_deg: F64, heading: F64) -> F64 | None:
    """(N, 3) vehicle-frame sun directions per point: the preset's sun, or a world-frame
    sun (azimuth, elevation deg) per point where ``sun_deg`` is finite; NaN rows: none;
    ``None`` when no point has a direct sun."""
    rows = _sun_rows(env, sun_deg)
    if not np.any(rows[:, 0] != SUN_NONE):
        return None
    return sun_directions_of(rows, heading)


__all__ = ["DT_S", "BatchTrace", "Evaluator", "Kinematics", "Trace", "kinematics",
           "kinematics_arrays"]
