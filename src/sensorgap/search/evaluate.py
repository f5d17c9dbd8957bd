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

import math
import threading
from collections import OrderedDict
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from sensorgap.config import EnvironmentConfig, TargetConfig, load_target
from sensorgap.config.reaction import (
    ReactionConfig,
    friction_source,
    load_friction,
    load_reaction,
    road_condition,
    unconfirmable,
)
from sensorgap.coverage import GridSpec, Scene
from sensorgap.coverage.body import (
    body_per_sensor_pd,
    body_points,
    body_samples,
    min_visible_fraction,
    occlusion_changes,
    take_points,
)
from sensorgap.coverage.fastlookup import (
    SUN_NONE,
    SUN_VEHICLE,
    SUN_WORLD,
    sun_directions_at,
    sun_directions_of,
)
from sensorgap.coverage.logmiss import (
    LogMissMaps,
    TrackLookup,
    also_glare_free,
    log_miss_of,
    lookup_log_miss_tracks,
    per_sensor_pd,
    point_evaluators,
    sensor_pd,
)
from sensorgap.coverage.occluders import ego_frame_boxes, may_hide
from sensorgap.coverage.scope import scene_scope
from sensorgap.coverage.sightline import perfect_confirmation_step, viewpoints
from sensorgap.errors import InputError
from sensorgap.models import Conditions, System
from sensorgap.models.system import Sensor
from sensorgap.scenarios.batch import ScenarioBatch, Tracks
from sensorgap.scenarios.family import Scenario
from sensorgap.scenarios.trajectory import DT_S, Trajectory
from sensorgap.search.fastkin import kinematics_kernel
from sensorgap.search.outcome import (
    G_M_S2,
    Encounter,
    Outcome,
    encounter_geometry,
    reaction_outcome,
)
from sensorgap.search.possible import StartReach, in_reach, occluder_contact, possible

F64 = NDArray[np.float64]

#: Lateral margin added to the half widths for "in the ego's path", m.
LATERAL_MARGIN_M = 0.2
#: Map extent (vehicle frame, m) and cell size of the lookup maps.
MAP_EXTENT = (-120.0, 260.0, -40.0, 40.0)
MAP_RESOLUTION_M = 0.5
#: Bins of the target's relative heading for the body lookup maps over a half turn (15 deg).
HEADING_BINS = 12


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
        # ASCII digits only: no sign, space or other script's digit (int() takes all
        # three); at most 9 (int() refuses more than 4,300)
        if len(parts) == 2 and all(p.isascii() and p.isdigit() and len(p) <= 9 for p in parts):
            m, n = int(parts[0]), int(parts[1])
            if 1 <= m <= n <= 50:
                return cls(kind="m_of_n", m=m, n=n)
        raise InputError(
            "detection",
            "",
            "expected 'cumulative' or M/N in ASCII digits (no spaces) with 1 <= M <= N <= 50 "
            f"(e.g. 3/5), got {text!r}",
        )

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
    #: target heading relative to the ego's, rad (0: same direction)
    psi: F64 | None = None
    #: (T, M, 7) occluder boxes in the ego frame per step, and their labels (issue #17)
    occluders: F64 | None = None
    occluder_labels: tuple[str, ...] = ()
    #: per-step Pd of the sensors that confirm a target for braking (None: ``pd``)
    pd_confirm: F64 | None = None

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

    def as_batch(self) -> BatchTrace:
        """This trace as a batch of one row (what the metrics evaluate: one implementation
        per metric, ``search.metrics``); cached."""
        hit = self.__dict__.get("_batch")
        if isinstance(hit, BatchTrace):
            return hit

        def row(a: F64) -> F64:
            return np.ascontiguousarray(a, dtype=np.float64)[None, :]

        lm = log_miss_of(self.pd) if self.log_miss is None else self.log_miss
        bt = BatchTrace(
            t=np.ascontiguousarray(self.t, dtype=np.float64),
            x=row(self.x),
            y=row(self.y),
            log_miss=row(lm),
            ttc=row(self.ttc),
            headway=row(self.headway),
            distance=row(self.distance),
            ego_speed=row(self.ego_speed),
            heading=row(self.heading),
            n=np.array([len(self.t)], dtype=np.int64),
            collided=np.array([self.collided]),
            duration_s=self.duration_s,
            rule=self.rule,
            psi=None if self.psi is None else row(self.psi),
            log_miss_confirm=None if self.pd_confirm is None else row(log_miss_of(self.pd_confirm)),
        )
        self.__dict__["_batch"] = bt
        return bt


@dataclass(frozen=True)
class Kinematics:
    """Ego-frame target position and criticality per step (before truncation); ``psi``:
    the target's heading relative to the ego's, rad."""

    x: F64
    y: F64
    headway: F64
    distance: F64
    psi: F64


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
            p = pd[:, j : j + 1]
            dist[:, 1:] = dist[:, 1:] * (1.0 - p) + dist[:, :-1] * p
            dist[:, 0] *= 1.0 - p[:, 0]
        out[:, k] = dist[:, m:].sum(axis=1)
    return out


def kinematics_arrays(
    ego: Tracks | Scenario, target_tracks: Tracks | None, system: System, target: TargetConfig
) -> Kinematics:
    """Target position in the ego frame and time headway (in path ahead only),
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

    def rows(a: F64) -> NDArray[np.float64]:
        return np.ascontiguousarray(a, dtype=np.float64).reshape(-1, shape[-1] if shape else 1)

    m = rows(np.asarray(e.x)).shape
    out = [np.empty(m) for _ in range(5)]
    kinematics_kernel(
        rows(e.x),
        rows(e.y),
        rows(e.heading),
        rows(e.speed),
        rows(g.x),
        rows(g.y),
        rows(g.heading),
        target.length_m,
        target.width_m,
        0.5 * body.width_m,
        body.x_front_m,
        body.x_rear_m,
        LATERAL_MARGIN_M,
        *out,
    )
    xr, yr, headway, dist, psi = (a.reshape(shape) for a in out)
    return Kinematics(xr, yr, headway, dist, psi)


def kinematics(sc: Scenario, system: System, target: TargetConfig) -> Kinematics:
    """Target position in the ego frame and time headway (in path ahead only)."""
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
    #: (B, T) target heading relative to the ego's, rad
    psi: F64 | None = None
    #: (B, T) fused ln P_miss of the sensors that confirm a target for braking (the
    #: reaction model's ``confirm_with``); ``None``: the same as ``log_miss``
    log_miss_confirm: F64 | None = None
    #: the planned world-frame states (ego rear axle, target centre)
    ego: Tracks | None = None
    target: Tracks | None = None
    #: per-row environment names
    env_names: NDArray[np.str_] | None = None
    #: the encounter geometry (path TTC, threat onset, overlap intervals) and what the
    #: collision outcome needs: the reaction model and the reachable deceleration per row
    encounter: Encounter | None = None
    reaction: ReactionConfig | None = None
    decel_m_s2: F64 | None = None
    #: (B, T, M, 7) occluder boxes in the ego frame per step (``coverage.occluders``)
    occluders: F64 | None = None
    #: occluder labels (M,)
    occluder_labels: tuple[str, ...] = ()
    #: (B,) step at which perfect perception confirms the target, limited to the line of
    #: sight past the occluders (``coverage.sightline``; -1: never); None: M - 1
    perfect_step: NDArray[np.int64] | None = None
    #: (B,) the rows whose collision outcome is worked out (the encounters the search may
    #: use, ``search.possible``; the others get the open-loop outcome); None: every row
    outcome_rows: NDArray[np.bool_] | None = None
    #: ((B,) first step at which an occluder overlaps the ego's body, -1 for none; (B,)
    #: which occluder; the occluders' labels) (``search.possible.occluder_contact``)
    occluder_contact: tuple[NDArray[np.int64], NDArray[np.int64], tuple[str, ...]] | None = None
    #: which confirming sensor has the target within reach at t = 0, for kinds that ask
    #: it to start out of reach (``search.possible.in_reach``); None: not asked
    start_reach: StartReach | None = None

    def __len__(self) -> int:
        return len(self.n)

    @cached_property
    def outcome(self) -> Outcome:
        """The collision outcome of every row (``search.outcome``)."""
        if self.encounter is None or self.reaction is None or self.decel_m_s2 is None:
            raise ValueError("this batch was evaluated without a reaction model")
        r = self.reaction
        return reaction_outcome(
            self.encounter,
            self.pd_confirm,
            self.n,
            r.confirm_m,
            r.confirm_n,
            r.latency_s,
            r.jerk_m_s3,
            self.decel_m_s2,
            self.perfect_step,
            self.outcome_rows,
        )

    @cached_property
    def pd_confirm(self) -> F64:
        """(B, T) per-step Pd of the confirming sensors (0 beyond the valid steps)."""
        lm = self.log_miss if self.log_miss_confirm is None else self.log_miss_confirm
        return np.asarray(-np.expm1(lm) + 0.0, dtype=np.float64)

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
            hit = (
                at_least_m_of_window_batch(self.pd, rule.m, rule.n) >= rule.threshold
            ) & self.valid
        return np.asarray(np.where(hit.any(axis=1), np.argmax(hit, axis=1), -1), dtype=np.int64)

    def row(self, i: int) -> Trace:
        """Scenario ``i`` as a ``Trace`` (its valid steps)."""
        k = int(self.n[i])
        return Trace(
            t=self.t[:k],
            x=self.x[i, :k],
            y=self.y[i, :k],
            pd=self.pd[i, :k],
            ttc=self.ttc[i, :k],
            headway=self.headway[i, :k],
            distance=self.distance[i, :k],
            ego_speed=self.ego_speed[i, :k],
            heading=self.heading[i, :k],
            collided=bool(self.collided[i]),
            duration_s=self.duration_s,
            rule=self.rule,
            log_miss=self.log_miss[i, :k],
            psi=None if self.psi is None else self.psi[i, :k],
            pd_confirm=self.pd_confirm[i, :k],
            extra=self.outcome_row(i),
            occluders=None if self.occluders is None else self.occluders[i, :k],
            occluder_labels=self.occluder_labels,
        )

    def outcome_row(self, i: int) -> dict[str, float]:
        """Row ``i`` of the collision outcome by field name (empty without a reaction
        model)."""
        if self.reaction is None:
            return {}
        o = self.outcome
        return {name: float(getattr(o, name)[i]) for name in o.__dataclass_fields__}


def _env_weather_key(env: EnvironmentConfig) -> str:
    return env.model_dump_json(exclude={"sun", "description", "sources"})


class Evaluator:
    """Pd per step for scenarios of one vehicle (caches scenes and lookup maps)."""

    def __init__(
        self,
        system: System,
        mode: str = "lookup",
        max_maps: int = 32,
        resolution_m: float = MAP_RESOLUTION_M,
        rule: DetectionRule | None = None,
        bodies: bool = True,
        reaction: ReactionConfig | None = None,
        friction: Mapping[str, float] | None = None,
    ) -> None:
        if mode not in ("lookup", "exact"):
            raise ValueError(f"mode must be 'lookup' or 'exact', got {mode!r}")
        self.system = system
        self.mode = mode
        #: targets are bodies (``coverage.body``); False: points (the paper's setting)
        self.bodies = bodies
        #: the vehicle's reaction model (its file's ``reaction``) and road friction
        self.reaction = reaction or load_reaction(system.config.reaction)
        self.friction = (
            dict(friction)
            if friction is not None
            else load_friction(friction_source(system.config.reaction))
        )
        types = set(self.reaction.confirm_with)
        #: sensor rows whose detections confirm a target for braking
        self.confirm_rows: tuple[int, ...] = tuple(
            i for i, sn in enumerate(system.sensors) if sn.type_name in types
        )
        moving_types = set(self.reaction.confirm_moving_with)
        #: sensor rows that confirm a target only while it moves over the ground at the
        #: reaction model's ``moving_min_speed_m_s`` or more (a radar suppressing
        #: stationary returns)
        self.moving_rows: tuple[int, ...] = tuple(
            i for i, sn in enumerate(system.sensors) if sn.type_name in moving_types
        )
        if not self.confirm_rows and not self.moving_rows:  # it could never brake
            why = unconfirmable(self.reaction, {sn.type_name for sn in system.sensors})
            raise InputError(system.source, "reaction", why or "no sensor can confirm")
        self.rule = rule or DetectionRule()
        self.resolution_m = resolution_m
        self.max_maps = max_maps
        self._maps: OrderedDict[tuple[str, str], LogMissMaps] = OrderedDict()
        self._scenes: dict[tuple[str, str], Scene] = {}
        self._targets: dict[str, TargetConfig] = {}
        #: the targets file ``_targets`` was filled from (a run's recorded copy): a class
        #: it lacks is refused, never taken from the shipped presets instead
        self.targets_source: str | None = None
        self.sensor_ids = system.sensor_ids()
        #: viewpoint of perfect perception (``coverage.sightline``): the driver's eye, m
        self.perfect_views = viewpoints(system.config.vehicle)
        #: point-sensor pairs evaluated exactly in lookup mode (glare, outside the map)
        self.exact_pairs = 0
        #: evaluate only the sensors that can reach a batch's region (``coverage.scope``)
        self.scoped = True
        #: sensors left out of some exact evaluation, and why
        self.scope_log: dict[str, str] = {}
        #: occluders of a scene hide parts of the target body (issue #17); False: the
        #: paper's empty road (occluders are ignored)
        self.occlusion = True
        self._lock = threading.RLock()

    # -- caches ------------------------------------------------------------------------
    def target(self, name: str) -> TargetConfig:
        """A target class by name (cached)."""
        if name not in self._targets:
            if self.targets_source is not None:
                raise InputError(
                    self.targets_source,
                    "targets",
                    f"no target class {name!r}; it defines {', '.join(self._targets) or 'none'}",
                )
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

    # -- points ----------------------------------------------------------------------
    def _scoped(
        self, scene: Scene, x: F64, y: F64, reach: float, pool: Sequence[Sensor] | None = None
    ) -> tuple[Sensor, ...]:
        """The sensors of ``pool`` (default: all) that can reach the region of the points
        (all of them when not scoped)."""
        if pool is not None and list(pool) != list(scene.sensors):
            return tuple(pool)
        if not (self.scoped and len(x)):
            return scene.sensors
        z0 = scene.target.reference_height_m
        scope = scene_scope(
            scene,
            np.array([x.min() - reach, y.min() - reach, z0]),
            np.array([x.max() + reach, y.max() + reach, z0]),
        )
        with self._lock:
            for sid, why in scope.skipped.items():
                self.scope_log[sid] = why
        return tuple(scope.sensors)

    def _reach(self, target: TargetConfig) -> float:
        """How far a body's outline reaches from its centre, m (0 for points)."""
        if not self.bodies:
            return 0.0
        return 0.5 * math.hypot(target.length_m, target.width_m) + 0.5 * target.height_m

    def per_sensor_pd(
        self,
        env: EnvironmentConfig,
        target: TargetConfig,
        heading: F64,
        x: F64,
        y: F64,
        exact: bool | None = None,
        psi: F64 | None = None,
        occluders: F64 | None = None,
    ) -> F64:
        """(S, N) per-sensor Pd at vehicle-frame target centres x, y (m) for ego headings
        (rad) and target headings ``psi`` relative to the ego (rad, default 0), always
        exact; bodies or points as the evaluator is set (``bodies``); ``occluders``: (N, M,
        7) boxes per point (``coverage.occluders``; bodies only, when ``occlusion``)."""
        scene = self.scene(env, target)
        dirs = Conditions.sun_directions(env, heading)
        x = np.asarray(x, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        if self.bodies:
            p = np.zeros(len(x)) if psi is None else np.asarray(psi, dtype=np.float64)
            return body_per_sensor_pd(
                scene, x, y, p, dirs, occluders=occluders if self.occlusion else None
            )[0]
        z = np.full(len(x), target.reference_height_m)
        return per_sensor_pd(scene, x, y, z, dirs)

    def visible_fraction(
        self, env: EnvironmentConfig, target: TargetConfig, x: F64, y: F64, psi: F64 | None = None
    ) -> F64:
        """(S, N) visible fraction of the target body's facing outline per sensor (points:
        1 where the centre is in view, else 0)."""
        scene = self.scene(env, target)
        x = np.asarray(x, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        p = np.zeros(len(x)) if psi is None else np.asarray(psi, dtype=np.float64)
        if self.bodies:
            return body_per_sensor_pd(scene, x, y, p, None)[1]
        z = np.full(len(x), target.reference_height_m)
        out = np.zeros((len(scene.sensors), len(x)))
        for i, sn in enumerate(scene.sensors):
            idx, _ = sensor_pd(scene, sn, x, y, z, None)
            out[i, idx] = 1.0
        return out

    def exact_per_sensor(
        self,
        scene: Scene,
        x: F64,
        y: F64,
        psi: F64,
        sun_dirs: F64 | None,
        occluders: F64 | None = None,
        sensors: Sequence[Sensor] | None = None,
    ) -> tuple[tuple[int, ...], F64]:
        """Exact per-sensor Pd of the sensors (default: all) that can reach the points:
        (rows, (S', N)); ``occluders`` (N, M, 7) per point (bodies, when ``occlusion``)."""
        # bodies: each sensor culls the poses its range and field of view cannot reach
        # (``coverage.body``), which subsumes the scene scope
        pool = scene.sensors if sensors is None else list(sensors)
        sensors = (
            pool if self.bodies else self._scoped(scene, x, y, self._reach(scene.target), pool)
        )
        rows = tuple(scene.sensors.index(sn) for sn in sensors)
        if self.bodies:
            occ = occluders if self.occlusion else None
            return rows, body_per_sensor_pd(scene, x, y, psi, sun_dirs, sensors, occ)[0]
        z = np.full(len(x), scene.target.reference_height_m)
        out = np.zeros((len(sensors), len(x)))
        for i, sn in enumerate(sensors):
            idx, pd = sensor_pd(scene, sn, x, y, z, sun_dirs)
            out[i, idx] = pd
        return rows, out

    def log_miss(
        self,
        env: EnvironmentConfig,
        target: TargetConfig,
        x: F64,
        y: F64,
        sun_dirs: F64 | None,
        psi: F64 | None = None,
    ) -> F64:
        """Fused ln P_miss of every sensor at vehicle-frame target centres (m) with
        per-point sun directions and relative headings (rad, default 0), exact."""
        scene = self.scene(env, target)
        p = np.zeros(len(x)) if psi is None else psi
        _, pd = self.exact_per_sensor(scene, x, y, p, sun_dirs)
        return np.asarray(log_miss_of(pd).sum(axis=0), dtype=np.float64)

    def fused_pd(
        self,
        env: EnvironmentConfig,
        target: TargetConfig,
        heading: F64,
        x: F64,
        y: F64,
        psi: F64 | None = None,
    ) -> F64:
        """Fused Pd (eq. 11) at the target centres, exact."""
        lm = self.log_miss(env, target, x, y, Conditions.sun_directions(env, heading), psi)
        return np.asarray(-np.expm1(lm) + 0.0, dtype=np.float64)

    def _outline(self, target: TargetConfig) -> F64:
        """The target body's footprint outline, (K, 2) m in the target frame: its samples'
        distinct (x, y) (cached per target class)."""
        cache: dict[str, F64] = self.__dict__.setdefault("_outlines", {})
        hit = cache.get(target.name)
        if hit is None:
            body = body_samples(target)
            hit = cache[target.name] = np.asarray(
                np.unique(np.round(np.column_stack([body.x, body.y]), 6), axis=0), dtype=np.float64
            )
        return hit

    def confirming(self, target_speed_m_s: float) -> tuple[int, ...]:
        """The sensor rows that confirm a target moving over the ground at
        ``target_speed_m_s`` (m/s): ``confirm_rows``, and ``moving_rows`` from the reaction
        model's ``moving_min_speed_m_s``."""
        if self.moving_rows and target_speed_m_s >= self.reaction.moving_min_speed_m_s:
            return tuple(sorted(self.confirm_rows + self.moving_rows))
        return self.confirm_rows

    def _track_lookup(
        self,
        maps: LogMissMaps,
        scene: Scene,
        kin: Kinematics,
        heading: F64,
        sun: F64,
        subset: tuple[int, ...] | None = None,
    ) -> TrackLookup:
        """The body maps and exact evaluators of one lookup pass over the sensor rows
        ``subset`` (default: the confirming sensors). Off the map and for glared cameras
        at the edge of their view the lookup evaluates the target's centre exactly (a
        proposal: far targets and field-of-view edges under glare; exact evaluation
        decides)."""
        t = kin.x.shape[1]
        xf, yf = kin.x.reshape(-1), kin.y.reshape(-1)
        subset = self.confirm_rows if subset is None else subset
        outline: F64 | None = None
        order: dict[int, int] | None = None
        if self.bodies:
            outline = self._outline(scene.target)
            # a minimum visible fraction f of the facing outline (about half of it): the
            # ceil(f K / 2)-th best of the K outline points
            order = {
                i: max(
                    0, math.ceil(min_visible_fraction(scene.sensors[i]) * len(outline) / 2.0) - 1
                )
                for i in subset
            }
            totals = maps.body_totals(
                outline,
                subset,
                HEADING_BINS,
                tuple(order[i] for i in subset),
                keep=tuple(i for i in subset if i in maps.signal),  # glare-prone cameras
            )
        else:
            totals = maps.body_totals(np.zeros((1, 2)), subset, 1)
        sensors = tuple(scene.sensors[i] for i in subset)
        z0 = scene.target.reference_height_m

        def dirs_at(flat: NDArray[np.int64]) -> F64:
            return sun_directions_at(sun, heading, flat, t)

        exact_points, exact_camera = point_evaluators(scene, xf, yf, z0, dirs_at, sensors)
        return TrackLookup(
            totals, kin.psi, frozenset(subset), exact_points, exact_camera, outline, order
        )

    # -- scenarios ---------------------------------------------------------------------
    def evaluate_batch(
        self,
        batch: ScenarioBatch,
        env_names: Sequence[str] | NDArray[np.str_],
        presets: Mapping[str, EnvironmentConfig],
        sun_deg: F64 | None = None,
        rows: NDArray[np.intp] | None = None,
        duration_s: float | None = None,
        collisions_only: bool = False,
    ) -> BatchTrace:
        """Evaluate the ``rows`` (default: all) of a batch.

        ``env_names[i]``: the preset of row i; ``sun_deg[i]`` (azimuth, elevation), deg:
        a world-frame sun replacing the preset's (NaN: keep the preset's sun). In
        ``exact`` mode every sensor is evaluated (``log_miss``) and the confirming ones
        fused apart (``log_miss_confirm``); in ``lookup`` mode only the confirming sensors
        are looked up (both fields hold them: the lookup proposes, ``exact`` decides). The
        reaction model's moving-only sensors (``moving_rows``) count as confirming at the
        steps where the target's ground speed reaches ``moving_min_speed_m_s``.
        ``collisions_only`` (the search's metrics): Pd is evaluated only on rows with an
        open-loop collision after t = 0, the only rows with a collision to avoid; on the
        others it stays 0 (their collision probability is exactly 0 and, their path TTC
        being infinite, so are the risk terms; their Pd columns are never shown); nor on
        the encounters the search may not use (``search.possible``), which it stores as
        infeasible with their metrics at 0.
        """
        target = self.target(batch.target_class)
        if rows is None or len(rows) == len(batch):
            rows = np.arange(len(batch))
            ego, tgt = batch.ego, batch.target
            occ_tracks = batch.occluders
        else:
            ego, tgt = batch.ego.take(rows), batch.target.take(rows)
            occ_tracks = tuple(o.take(rows) for o in batch.occluders)
        kin = kinematics_arrays(ego, tgt, self.system, target)
        occ: F64 | None = None
        if occ_tracks and self.bodies:
            occ = ego_frame_boxes(
                ego.x,
                ego.y,
                ego.heading,
                np.stack([o.tracks.x for o in occ_tracks]),
                np.stack([o.tracks.y for o in occ_tracks]),
                np.stack([o.tracks.heading for o in occ_tracks]),
                np.array([[o.length_m, o.width_m, o.height_m] for o in occ_tracks]),
            )
        b, t = kin.x.shape
        body = self.system.config.vehicle
        enc = encounter_geometry(
            ego,
            tgt,
            float(batch.t[1] - batch.t[0]),
            (target.length_m, target.width_m),
            (body.x_front_m, body.x_rear_m, body.width_m),
            self.reaction.threat_margin_m,
            self.reaction.threat_horizon_s,
            self.reaction.threat_prediction_s,
            ego_frame_x=kin.x,
        )
        collided = enc.collide_step >= 0
        n = np.where(collided, enc.collide_step + 1, t).astype(np.int64)
        look = enc.collide_step > 0
        contact = None  # an occluder on the ego's body: an impossible encounter
        if occ is not None:
            step, which = occluder_contact(occ, n, body.x_front_m, body.x_rear_m, body.width_m)
            contact = (step, which, tuple(o.label for o in occ_tracks))
        reach = self.start_reach(kin, tgt, target) if batch.start_out_of_reach else None
        usable: NDArray[np.bool_] | None = None
        if collisions_only:  # the search stores the others as infeasible (search.possible)
            usable = possible(
                enc,
                kin.x,
                kin.psi,
                body.x_front_m,
                target.length_m,
                target.width_m,
                None if contact is None else contact[0],
                None if reach is None else reach.sensor,
            )
            look &= usable
        valid = np.arange(t)[None, :] < n[:, None]
        #: where the reaction model's moving-only sensors confirm (target ground speed)
        moving = tgt.speed >= self.reaction.moving_min_speed_m_s if self.moving_rows else None
        log_miss = np.zeros((b, t))
        log_conf: F64 | None = None
        names = np.asarray(env_names)[rows]
        sun = (
            np.full((b, 2), np.nan)
            if sun_deg is None
            else np.asarray(sun_deg, dtype=np.float64)[rows]
        )
        if self.mode == "exact" and len(self.confirm_rows) < len(self.system.sensors):
            log_conf = np.zeros((b, t))
        groups = [(str(name), np.flatnonzero(names == name)) for name in np.unique(names)]
        for name, g in groups:
            env = presets[name]
            if collisions_only:
                g = g[look[g]]
                if not g.size:
                    continue
            scene = self.scene(env, target)
            if self.mode == "lookup":
                sun_rows = _sun_rows(env, sun)
                maps = self.maps(env, target)
                pass_in = _PassInputs(
                    maps, scene, env, kin, ego.heading, sun, sun_rows, valid, n, occ
                )
                if moving is None:
                    n_exact = self._lookup_pass(pass_in, g, self.confirm_rows, log_miss)
                else:  # the moving-only sensors confirm only where the target moves
                    n_exact = self._moving_lookup(pass_in, g, moving, log_miss)
                with self._lock:
                    self.exact_pairs += n_exact
                continue
            vr, vc = np.nonzero(valid[g])
            gr = g[vr]
            dirs = _sun_directions(env, sun[gr], ego.heading[gr, vc])
            srows, pd = self.exact_per_sensor(
                scene,
                kin.x[gr, vc],
                kin.y[gr, vc],
                kin.psi[gr, vc],
                dirs,
                None if occ is None else occ[gr, vc],
            )
            lm = log_miss_of(pd)
            log_miss[gr, vc] = lm.sum(axis=0)
            if log_conf is not None:
                keep = [i for i, r in enumerate(srows) if r in self.confirm_rows]
                log_conf[gr, vc] = lm[keep].sum(axis=0)
                if moving is not None:  # confirming only where the target moves
                    mv = [i for i, r in enumerate(srows) if r in self.moving_rows]
                    log_conf[gr, vc] += np.where(moving[gr, vc], lm[mv].sum(axis=0), 0.0)
        ttc = np.where(valid, enc.ttc_path, np.inf)
        headway = np.where(valid, kin.headway, np.inf)
        perfect: NDArray[np.int64] | None = None
        if occ is not None and self.occlusion:  # perfect perception sees what is in sight
            need = np.flatnonzero((enc.collide_step >= 0) & (enc.threat_step >= 0))
            perfect = perfect_confirmation_step(
                kin.x,
                kin.y,
                kin.psi,
                n,
                occ,
                target,
                self.perfect_views,
                self.reaction.confirm_m,
                self.reaction.confirm_n,
                need.astype(np.int64),
            )
        decel = np.zeros(b)
        for name, g in groups:  # per environment: its road's friction
            decel[g] = min(
                self.reaction.decel_max_m_s2,
                self.friction[road_condition(presets[name])] * G_M_S2,
            )
        return BatchTrace(
            t=batch.t,
            x=kin.x,
            y=kin.y,
            log_miss=log_miss,
            ttc=ttc,
            headway=headway,
            distance=kin.distance,
            ego_speed=ego.speed,
            heading=ego.heading,
            n=n,
            collided=collided,
            duration_s=float(batch.t[-1]) if duration_s is None else duration_s,
            rule=self.rule,
            psi=kin.psi,
            log_miss_confirm=log_conf,
            ego=ego,
            target=tgt,
            env_names=names,
            encounter=enc,
            reaction=self.reaction,
            decel_m_s2=decel,
            occluders=occ if self.occlusion else None,
            occluder_labels=tuple(o.label for o in occ_tracks) if self.occlusion else (),
            perfect_step=perfect,
            outcome_rows=usable,
            occluder_contact=contact,
            start_reach=reach,
        )

    def start_reach(self, kin: Kinematics, tgt: Tracks, target: TargetConfig) -> StartReach:
        """Which confirming sensor has the target within reach at t = 0
        (``search.possible.in_reach``; ``kin``: (B, T) ego-frame kinematics, m and rad;
        ``tgt``: the target's states): those of ``confirm_rows``, and of ``moving_rows``
        where the target moves at ``moving_min_speed_m_s`` or more at t = 0 (a radar that
        confirms only moving targets cannot confirm a stopped car, whatever its reach)."""
        rows = sorted(set(self.confirm_rows) | set(self.moving_rows))
        mounts = [self.system.sensors[i].mount for i in rows]
        reach = [(m.x, m.y, m.max_range) for m in mounts]
        counts = None
        if self.moving_rows:  # a moving-only sensor counts where the target moves at t = 0
            moving = tgt.speed[:, 0] >= self.reaction.moving_min_speed_m_s
            moving_only = np.array([i in self.moving_rows for i in rows])
            counts = ~moving_only[None, :] | moving[:, None]
        which, dist = in_reach(
            kin.x[:, 0], kin.y[:, 0], kin.psi[:, 0], target.length_m, target.width_m, reach, counts
        )
        return StartReach(
            which,
            dist,
            tuple(self.sensor_ids[i] for i in rows),
            tuple(m.max_range for m in mounts),
            target.name,
        )

    def _moving_lookup(
        self, a: _PassInputs, g: NDArray[np.intp], moving: NDArray[np.bool_], log_miss: F64
    ) -> int:
        """Lookup mode with moving-only sensors (``moving_rows``): the confirming sensors
        into ``log_miss`` and, at the steps where the target moves (``moving``, (B, T)),
        the moving-only ones added; one compiled pass for both when the moving-only
        sensors hold no glare-prone one (``also_glare_free``), else a pass each. The
        occluded steps of each set are evaluated exactly before the sum, as in two passes.
        Returns the point-sensor pairs evaluated exactly."""
        gm = g[moving[g].any(axis=1)]
        if not gm.size:
            return self._lookup_pass(a, g, self.confirm_rows, log_miss)
        extra = np.zeros_like(log_miss)
        if not also_glare_free(a.scene, self.moving_rows):
            n_exact = self._lookup_pass(a, g, self.confirm_rows, log_miss)
            n_exact += self._lookup_pass(a, gm, self.moving_rows, extra)
        else:
            also = self._track_lookup(
                a.maps, a.scene, a.kin, a.heading, a.sun_rows, self.moving_rows
            )
            n_exact = self._lookup_pass(a, g, self.confirm_rows, log_miss, (also, moving, extra))
            if a.occ is not None and self.occlusion:
                n_exact += self._occluded_exact(a, gm, extra, self.moving_rows)
        log_miss[gm] += np.where(moving[gm], extra[gm], 0.0)
        return n_exact

    def _lookup_pass(
        self,
        a: _PassInputs,
        g: NDArray[np.intp],
        subset: tuple[int, ...],
        out: F64,
        also: tuple[TrackLookup, NDArray[np.bool_], F64] | None = None,
    ) -> int:
        """One lookup pass of the sensor rows ``subset`` over the rows ``g`` into ``out``
        (ln P_miss, (B, T)), the steps an occluder may change evaluated exactly (``also``:
        a second sensor set looked up in the same pass, ``lookup_log_miss_tracks``; its
        occluded steps are the caller's); returns the point-sensor pairs evaluated
        exactly."""
        tl = self._track_lookup(a.maps, a.scene, a.kin, a.heading, a.sun_rows, subset)
        pairs = lookup_log_miss_tracks(
            a.maps, a.scene, a.kin.x, a.kin.y, a.heading, a.n, g, a.sun_rows, out, tl, also
        )
        if a.occ is not None and self.occlusion:
            pairs += self._occluded_exact(a, g, out, subset)
        return pairs

    def _occluded_exact(
        self, a: _PassInputs, g: NDArray[np.intp], log_miss: F64, subset: tuple[int, ...]
    ) -> int:
        """Lookup mode with occluders (``a.occ``): at the valid steps of rows ``g`` where an
        occluder may hide part of the target (``coverage.occluders.may_hide``), the sensor
        rows ``subset`` are evaluated exactly with the occluders, replacing the map's value
        in ``log_miss`` (the maps know no occluders). Returns how many point-sensor pairs
        were evaluated."""
        scene, kin, occ = a.scene, a.kin, a.occ
        assert occ is not None
        vr, vc = np.nonzero(a.valid[g])
        gr = g[vr]
        if not gr.size:
            return 0
        target = scene.target
        radius = 0.5 * math.hypot(target.length_m, target.width_m)
        mount_r = max(math.hypot(s.mount.x, s.mount.y) for s in scene.sensors)
        hit = may_hide(occ[gr, vc], kin.x[gr, vc], kin.y[gr, vc], radius, mount_r)
        gr, vc = gr[hit], vc[hit]
        if not gr.size:
            return 0
        sensors = [scene.sensors[i] for i in subset]
        # where the occluders hide no sample from the confirming sensors the maps' value
        # stands (geometry only, cheap); the body samples are computed once for both steps
        x, y, psi = kin.x[gr, vc], kin.y[gr, vc], kin.psi[gr, vc]
        pts = body_points(body_samples(target), x, y, psi)
        boxes = occ[gr, vc]
        hit = occlusion_changes(scene, x, y, psi, boxes, sensors, pts)
        gr, vc = gr[hit], vc[hit]
        if not gr.size:
            return 0
        dirs = _sun_directions(a.env, a.sun[gr], a.heading[gr, vc])
        # occluders exist only with target bodies (``evaluate_batch``): exact body Pd
        pd = body_per_sensor_pd(
            scene, x[hit], y[hit], psi[hit], dirs, sensors, boxes[hit], take_points(pts, hit)
        )[0]
        log_miss[gr, vc] = log_miss_of(pd).sum(axis=0)
        return int(gr.size * len(sensors))

    def trace(self, sc: Scenario, env: EnvironmentConfig, duration_s: float) -> Trace:
        """Evaluate one generated scenario in ``env`` (a batch of one)."""
        batch = ScenarioBatch.of(sc)
        return self.evaluate_batch(batch, ["env"], {"env": env}, duration_s=duration_s).row(0)


@dataclass(frozen=True)
class _PassInputs:
    """What every lookup pass of one environment group of ``evaluate_batch`` reads: the
    maps and scene, the environment, the (B, T) kinematics, ego heading (rad), per-row sun
    (``sun`` (B, 2) deg as given, ``sun_rows`` (B, 3) as ``_sun_rows``), the valid steps,
    steps per row ``n`` and the (B, T, K, ...) occluder boxes (or None)."""

    maps: LogMissMaps
    scene: Scene
    env: EnvironmentConfig
    kin: Kinematics
    heading: F64
    sun: F64
    sun_rows: F64
    valid: NDArray[np.bool_]
    n: NDArray[np.int64]
    occ: F64 | None


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


__all__ = [
    "DT_S",
    "BatchTrace",
    "Evaluator",
    "Kinematics",
    "Trace",
    "kinematics",
    "kinematics_arrays",
]
