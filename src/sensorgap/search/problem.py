"""A search problem: one family x environments, unit cube -> candidate -> metrics.

Dimensions: ``environment`` (choice of the given presets), then, with ``sun_search``,
``sun_azimuth_deg`` [0, 360) (world frame, clockwise from north, 1 deg steps) and
``sun_elevation_deg`` [2, 30] (1 deg steps) — applied only to environments whose preset has
a visible sun (others ignore them and record no sun) — then the family's parameters.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from functools import cached_property, partial

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sensorgap.config import EnvironmentConfig
from sensorgap.errors import InputError
from sensorgap.scenarios.family import Family, Param, ParamValue, Scenario
from sensorgap.search.evaluate import Evaluator, Trace
from sensorgap.search.metrics import compute_all_batch, metric_names, summary
from sensorgap.search.possible import encounter_problems
from sensorgap.search.speedlimit import SpeedLimit, speed_limit

F64 = NDArray[np.float64]

SUN_AZIMUTH = Param("sun_azimuth_deg", 0.0, 359.0, unit="deg")
SUN_ELEVATION = Param("sun_elevation_deg", 2.0, 30.0, unit="deg")
#: The family parameter bounded by the environment's lawful speed (``search.speedlimit``).
EGO_SPEED = "ego_speed_m_s"


#: Smallest chunk worth a thread of its own, candidates.
MIN_ROWS_PER_THREAD = 64
#: Largest piece of a batch evaluated at once, candidates: 1,024 x 201 steps keeps each
#: (B, T) float64 array at 1.6 MB, within the caches (``benchmarks/bench_search.py``).
PIECE_ROWS = 1024
#: Continuous parameters are rounded to this many decimals (their units: m, s, m/s), so
#: stored and exported values are short and regenerate the evaluated scenario exactly.
PARAM_DECIMALS = 4


_POOLS: dict[tuple[int, int], ThreadPoolExecutor] = {}
_POOLS_LOCK = threading.Lock()


def _pool(threads: int) -> ThreadPoolExecutor:
    """A process-wide pool of ``threads`` worker threads (created once, reused)."""
    key = (os.getpid(), threads)  # a forked child must not reuse its parent's threads
    with _POOLS_LOCK:
        pool = _POOLS.get(key)
        if pool is None:
            pool = _POOLS[key] = ThreadPoolExecutor(
                max_workers=threads, thread_name_prefix="sensorgap-eval"
            )
        return pool


def _canon(v: ParamValue) -> ParamValue:
    return v if isinstance(v, str) else float(np.round(float(v), PARAM_DECIMALS))


def decode_column(p: Param, u: F64) -> NDArray[np.float64] | NDArray[np.str_]:
    """Vectorised ``Param.decode`` (+ rounding of continuous values): (B,) unit values ->
    (B,) parameter values."""
    u = np.clip(np.asarray(u, dtype=np.float64), 0.0, 1.0)
    if p.categorical:
        k = np.minimum((u * len(p.choices)).astype(np.int64), len(p.choices) - 1)
        return np.asarray(p.choices)[k]
    return np.round(p.low + u * (p.high - p.low), PARAM_DECIMALS)


@dataclass
class Decoded:
    """B decoded unit vectors of one problem: environment preset names, world-frame sun
    (azimuth, elevation deg; NaN when the preset has no visible sun or the sun is not
    searched) and the family's parameter columns."""

    env_names: NDArray[np.str_]
    sun_deg: F64
    params: dict[str, NDArray[np.float64] | NDArray[np.str_]]

    def __len__(self) -> int:
        return len(self.env_names)

    def take(self, rows: NDArray[np.intp]) -> Decoded:
        """The selected rows."""
        return Decoded(
            self.env_names[rows], self.sun_deg[rows], {k: v[rows] for k, v in self.params.items()}
        )


@dataclass
class BatchOutcome:
    """Metrics of B candidates: (B,) arrays per metric (0 for infeasible rows), the
    feasibility and the reason of each infeasible row, and the search objective."""

    metrics: dict[str, F64]
    feasible: NDArray[np.bool_]
    notes: list[str]
    objective: F64 | None = None


#: The search objective's floor for targets that become a threat, log10: far below any
#: reachable log10 risk (201 steps x 40 sensors x ln(2^-53) / ln 10 = -1.3e5).
OBJECTIVE_THREAT_FLOOR = -1.0e6
#: Search objective of an infeasible candidate (below every feasible one).
OBJECTIVE_INFEASIBLE = -1.0e7
#: Key of the search objective among a result's stored values (not a ranking column).
OBJECTIVE_KEY = "search_objective"


#: A scenario is sensor-critical only when perfect perception avoids the collision with at
#: least this much to spare, s: one confirmation window of the presets (N = 5 cycles at
#: 20 Hz). Closer to the edge of physics it is *marginal*: only ideal perception avoids it
#: (any real sensor, Pd < 1, loses that much in confirming), so it says nothing about this
#: vehicle's sensors. The search steers away from it like from unavoidable encounters
#: (``ranking.classify``).
MIN_PERFECT_MARGIN_S = 0.25


def enough_margin(perfect_margin_s: ArrayLike) -> NDArray[np.bool_]:
    """Whether perfect perception avoids with at least ``MIN_PERFECT_MARGIN_S`` (s) to
    spare (NaN, where it collides too: False); the one test behind ``ranking.classify``,
    the search objective and the benchmarks."""
    return np.asarray(perfect_margin_s, dtype=np.float64) >= MIN_PERFECT_MARGIN_S - 1e-9


#: Search objective of a candidate whose collision is unavoidable even with perfect
#: perception (not a sensor weakness): below every avoidable threat.
OBJECTIVE_UNAVOIDABLE = -2.0e6
#: log10 of collision probabilities below which the graded risk takes over.
LOG10_P_FLOOR = -300.0


def search_objective(
    log10_risk_raw: F64,
    min_distance_m: F64,
    collision_probability: F64 | None = None,
    collision_perfect: F64 | None = None,
    perfect_margin_s: F64 | None = None,
) -> F64:
    """What the strategies maximise. With the collision outcome: ``log10`` of the
    collision probability where it is above 1e-300; below that (or 0) the unfloored log10
    risk minus 1000 (see below), so the strategies still climb towards encounters that
    come close to going unconfirmed; unavoidable candidates (a collision even with perfect
    perception) score ``OBJECTIVE_UNAVOIDABLE``, and so do marginal ones
    (``perfect_margin_s`` below ``MIN_PERFECT_MARGIN_S``: avoidable only by ideal
    perception). The graded part: the log10 risk *without* the ranking's floor of -300
    where the target becomes a threat (a finite path TTC after the lead-in), else
    ``OBJECTIVE_THREAT_FLOOR - min distance (m, at most 600)``."""
    raw = np.asarray(log10_risk_raw, dtype=np.float64)
    graded = np.where(
        np.isfinite(raw),
        np.maximum(raw, OBJECTIVE_THREAT_FLOOR),
        OBJECTIVE_THREAT_FLOOR - np.minimum(min_distance_m, 600.0),
    )
    if collision_probability is None or collision_perfect is None:
        return graded
    p = np.asarray(collision_probability, dtype=np.float64)
    with np.errstate(divide="ignore"):
        lp = np.log10(np.maximum(p, 0.0))
    out = np.where(lp > LOG10_P_FLOOR, lp, np.minimum(graded, 0.0) - 1000.0)
    lost = np.asarray(collision_perfect) > 0.5
    if perfect_margin_s is not None:
        lost |= (p > 0.0) & ~enough_margin(perfect_margin_s)
    return np.where(lost, OBJECTIVE_UNAVOIDABLE, out)


@dataclass(frozen=True)
class Candidate:
    """One point of the search: family, environment (+ sun), parameters."""

    family: str
    environment: str
    sun: tuple[float, float] | None
    params: dict[str, ParamValue]

    @cached_property
    def scenario_id(self) -> str:
        """Stable 12-hex id of (family, environment, sun, parameters)."""
        text = json.dumps(
            [self.family, self.environment, self.sun, sorted(self.params.items())], sort_keys=True
        )
        return hashlib.sha256(text.encode()).hexdigest()[:12]

    @property
    def environment_label(self) -> str:
        """``name`` or ``name@az/el`` with the world-frame sun."""
        if self.sun is None:
            return self.environment
        az = f"{self.sun[0]:g}"
        if az == "360":  # 359.9999995 and up: '360' is no azimuth a label may give back
            az = repr(float(self.sun[0]))  # (hostile round 41, a remark)
        return f"{self.environment}@sun{az}/{self.sun[1]:g}"


@dataclass
class Result:
    """An evaluated candidate. ``feasible`` False: no trajectory (``note`` says why)."""

    candidate: Candidate
    metrics: dict[str, float]
    feasible: bool
    note: str = ""
    trace: Trace | None = field(default=None, repr=False)

    @property
    def risk(self) -> float:
        """The risk, a probability (0 for infeasible candidates)."""
        return float(self.metrics.get("risk", 0.0)) if self.feasible else 0.0

    @property
    def objective(self) -> float:
        """What the strategies maximise (``search_objective``; stored with the metrics
        under ``OBJECTIVE_KEY`` so a resumed search replays the same decisions)."""
        return float(
            self.metrics.get(OBJECTIVE_KEY, self.score if self.feasible else OBJECTIVE_INFEASIBLE)
        )

    @property
    def score(self) -> float:
        """The ranking score: log10 of the risk (-300 when infeasible)."""
        if not self.feasible:
            return -300.0
        return float(self.metrics.get("log10_risk", -300.0))


def _per_environment(names: NDArray[np.str_], value: Callable[[str], float]) -> F64:
    """(B,) ``value`` of each row's environment name, evaluated once per distinct name."""
    uniq, inverse = np.unique(np.asarray(names), return_inverse=True)
    return np.array([value(str(n)) for n in uniq], dtype=np.float64)[inverse.reshape(-1)]


class SearchProblem:
    """Maps unit-cube vectors of one family to evaluated candidates."""

    def __init__(
        self,
        family: Family,
        environments: dict[str, EnvironmentConfig],
        evaluator: Evaluator,
        sun_search: bool = True,
    ) -> None:
        if not environments:
            raise InputError("environments", "", "give at least one environment")
        self.family = family
        self.environments = environments
        self.evaluator = evaluator
        self.env_names = tuple(environments)
        self.sun_search = sun_search and any(
            e.sun is not None and e.sun.visible for e in environments.values()
        )
        dims = [Param("environment", choices=self.env_names)]
        if self.sun_search:
            dims += [SUN_AZIMUTH, SUN_ELEVATION]
        self.space: tuple[Param, ...] = (*dims, *family.space)
        self._n_env = len(dims)
        #: per environment: the lawful ego speed bound (driving within sight); the ego
        #: speed dimension spans ``[low, min(high, bound)]`` in each environment, and a row
        #: above the bound (``evaluate`` with given values) is infeasible
        self._ego_speed = next((p for p in family.space if p.name == EGO_SPEED), None)
        self.speed_limits: dict[str, SpeedLimit] = {
            n: self._with_top_speed(speed_limit(e, evaluator.reaction, evaluator.friction))
            for n, e in environments.items()
        }

    def _with_top_speed(self, lim: SpeedLimit) -> SpeedLimit:
        """``lim``, or the vehicle's top speed (``vehicle.max_speed_m_s``) where that binds
        first within the family's ego speeds: an ego cannot drive faster than it can (and
        an exported scenario asking it to would not play as planned)."""
        top = self.evaluator.system.config.vehicle.max_speed_m_s
        if self._ego_speed is None or top >= min(lim.speed_m_s, self._ego_speed.high):
            return lim
        return SpeedLimit(
            top,
            lim.visibility_m,
            f"the vehicle's top speed {top * 3.6:.0f} km/h (vehicle.max_speed_m_s)",
        )

    def ego_speed_range(self, env: str) -> tuple[float, float]:
        """The ego speed range searched in environment ``env``, m/s: the family's range cut
        at the environment's lawful speed (empty, ``high < low``, when the bound is below
        the family's lowest speed)."""
        p = self._ego_speed
        if p is None:
            raise InputError("family", self.family.name, f"has no {EGO_SPEED} parameter")
        bound = self.speed_limits[env].speed_m_s
        if bound >= p.high:
            return p.low, p.high
        scale = 10.0**PARAM_DECIMALS  # cut down to the rounding grid: decoded <= bound
        return p.low, math.floor(bound * scale) / scale

    def _speed_highs(self, names: NDArray[np.str_]) -> F64:
        """(B,) upper ends of the ego speed dimension per row's environment, m/s (at least
        the family's low end, so the decoded value stays in the family's range)."""
        assert self._ego_speed is not None
        low = self._ego_speed.low
        return _per_environment(names, lambda n: max(low, self.ego_speed_range(n)[1]))

    @property
    def dim(self) -> int:
        """Number of dimensions."""
        return len(self.space)

    @property
    def levels(self) -> list[int | None]:
        """Choices per dimension (None: continuous)."""
        return [len(p.choices) if p.categorical else None for p in self.space]

    def decode(self, u: F64) -> Candidate:
        """Unit-cube vector -> candidate."""
        env = str(self.space[0].decode(float(u[0])))
        sun = None
        cfg = self.environments[env]
        if self.sun_search and cfg.sun is not None and cfg.sun.visible:
            sun = (
                float(round(float(self.space[1].decode(float(u[1]))))),
                float(round(float(self.space[2].decode(float(u[2]))))),
            )
        params = {
            p.name: _canon(p.decode(float(v)))
            for p, v in zip(self.family.space, u[self._n_env :], strict=True)
        }
        if self._ego_speed is not None:
            j = self._n_env + self.family.space.index(self._ego_speed)
            params[EGO_SPEED] = self._decode_speed(np.array([u[j]]), np.array([env]))[0]
        return Candidate(self.family.name, env, sun, params)

    def _decode_speed(self, u: F64, names: NDArray[np.str_]) -> F64:
        """Ego speed column of unit values ``u`` in each row's environment, m/s (rounded
        like every continuous parameter)."""
        assert self._ego_speed is not None
        low = self._ego_speed.low
        high = self._speed_highs(names)
        return np.round(low + np.clip(u, 0.0, 1.0) * (high - low), PARAM_DECIMALS)

    def decode_batch(self, U: F64) -> Decoded:
        """(B, dim) unit-cube rows -> decoded columns (same values as ``decode``)."""
        U = np.asarray(U, dtype=np.float64).reshape(-1, self.dim)
        names = decode_column(self.space[0], U[:, 0]).astype(str)
        sun = np.full((len(U), 2), np.nan)
        if self.sun_search:
            visible = [n for n in self.env_names if self._visible_sun(n)]
            rows = np.isin(names, np.asarray(visible, dtype=str))
            az = np.round(
                self.space[1].low
                + np.clip(U[:, 1], 0, 1) * (self.space[1].high - self.space[1].low)
            )
            el = np.round(
                self.space[2].low
                + np.clip(U[:, 2], 0, 1) * (self.space[2].high - self.space[2].low)
            )
            sun[rows, 0], sun[rows, 1] = az[rows], el[rows]
        params = {
            p.name: decode_column(p, U[:, self._n_env + j]) for j, p in enumerate(self.family.space)
        }
        if self._ego_speed is not None:
            j = self._n_env + self.family.space.index(self._ego_speed)
            params[EGO_SPEED] = self._decode_speed(U[:, j], names)
        return Decoded(names, sun, params)

    def _visible_sun(self, name: str) -> bool:
        sun = self.environments[name].sun
        return sun is not None and sun.visible

    def candidates(self, d: Decoded) -> list[Candidate]:
        """Candidate objects of decoded rows (ids for the store and the ranking)."""
        names = [p.name for p in self.family.space]
        cols = [d.params[n].tolist() for n in names]
        envs = d.env_names.tolist()
        sun = d.sun_deg.tolist()
        out = []
        for i in range(len(d)):
            s = None if sun[i][0] != sun[i][0] else (float(sun[i][0]), float(sun[i][1]))
            out.append(
                Candidate(
                    self.family.name,
                    envs[i],
                    s,
                    {n: c[i] for n, c in zip(names, cols, strict=True)},
                )
            )
        return out

    def evaluate_decoded(
        self, d: Decoded, threads: int = 1, collisions_only: bool = True
    ) -> BatchOutcome:
        """Generate and evaluate decoded rows; every metric per row. Rows are evaluated in
        contiguous pieces of at most ``PIECE_ROWS`` (their (B, T) arrays stay in the CPU
        caches), on ``threads`` threads when > 1 (the compiled kernels and numpy release
        the GIL); every row's values are independent of the piece it is in, so the result
        is identical for any ``threads``. ``collisions_only`` (the search): Pd is evaluated
        only on rows with a collision to avoid (``Evaluator.evaluate_batch``); the
        detection metrics of the other rows are then 0, not measured."""
        n = len(d)
        k = max(1, min(threads, n // MIN_ROWS_PER_THREAD))
        n_pieces = max(k, -(-n // PIECE_ROWS))
        run = partial(self._evaluate_rows, collisions_only=collisions_only)
        if n_pieces == 1:
            return run(d)
        bounds = np.linspace(0, n, n_pieces + 1).astype(int)
        parts = [d.take(np.arange(a, b)) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
        if k > 1:
            for name in np.unique(d.env_names):  # build shared caches before the threads
                self.evaluator.prepare(
                    self.environments[str(name)], self.evaluator.target(self.family.target_class)
                )
            outs = list(_pool(k).map(run, parts))
        else:
            outs = [run(p) for p in parts]
        return BatchOutcome(
            {m: np.concatenate([o.metrics[m] for o in outs]) for m in outs[0].metrics},
            np.concatenate([o.feasible for o in outs]),
            [note for o in outs for note in o.notes],
            np.concatenate([o.objective for o in outs if o.objective is not None]),
        )

    def _evaluate_rows(self, d: Decoded, collisions_only: bool = True) -> BatchOutcome:
        batch = self.family.generate_batch(d.params)
        ok = np.flatnonzero(batch.ok)
        names = metric_names()
        metrics = {m: np.zeros(len(d)) for m in names}
        feasible, notes = batch.ok.copy(), list(batch.notes)
        if self._ego_speed is not None:  # above the environment's lawful speed
            speed = np.asarray(d.params[EGO_SPEED], dtype=np.float64)
            bound = _per_environment(d.env_names, lambda n: self.speed_limits[n].speed_m_s)
            for i in np.flatnonzero(feasible & (speed > bound + 1e-9)):
                feasible[i] = False
                lim = self.speed_limits[str(d.env_names[i])]
                notes[i] = (
                    f"ego speed {speed[i] * 3.6:.0f} km/h above the lawful speed in "
                    f"{d.env_names[i]}: {lim.rule}"
                )
            ok = np.flatnonzero(feasible)
        objective = np.full(len(d), OBJECTIVE_INFEASIBLE)
        if ok.size:
            bt = self.evaluator.evaluate_batch(
                batch,
                d.env_names,
                self.environments,
                d.sun_deg,
                rows=ok,
                duration_s=self.family.duration_s,
                collisions_only=collisions_only,
            )
            for m, v in compute_all_batch(bt, names).items():
                metrics[m][ok] = v
            sm = summary(bt).values
            min_dist, raw = sm["min_distance"], sm["log10_risk_raw"]
            objective[ok] = search_objective(
                raw,
                min_dist,
                metrics["collision_probability"][ok],
                metrics["collision_perfect"][ok],
                metrics["perfect_margin_s"][ok],
            )
            target = self.evaluator.target(self.family.target_class)
            body = self.evaluator.system.config.vehicle
            assert bt.encounter is not None
            bad = encounter_problems(
                bt.encounter,
                bt.t,
                bt.x,
                bt.psi,
                body.x_front_m,
                target.length_m,
                target.width_m,
                bt.occluder_contact,
                bt.start_reach,
            )
            for j, note in bad:
                notes[ok[j]] = note
            drop = ok[np.array([j for j, _ in bad], dtype=np.intp)]
            feasible[drop] = False
            for m in names:
                metrics[m][drop] = 0.0
            objective[drop] = OBJECTIVE_INFEASIBLE
        return BatchOutcome(metrics, feasible, notes, objective)

    def results(self, cands: list[Candidate], out: BatchOutcome) -> list[Result]:
        """``Result`` objects of an evaluated batch."""
        names = list(out.metrics)
        cols = [out.metrics[n].tolist() for n in names]
        feas = out.feasible.tolist()
        obj = (
            np.full(len(cands), OBJECTIVE_INFEASIBLE) if out.objective is None else out.objective
        ).tolist()
        res = []
        for i, c in enumerate(cands):
            vals = (
                dict(zip(names, (col[i] for col in cols), strict=True))
                if feas[i]
                else {n: 0.0 for n in names}
            )
            vals[OBJECTIVE_KEY] = obj[i]
            res.append(Result(c, vals, bool(feas[i]), "" if feas[i] else out.notes[i]))
        return res

    def environment(self, cand: Candidate) -> EnvironmentConfig:
        """The environment of a candidate (the preset with its world-frame sun)."""
        env = self.environments[cand.environment]
        if cand.sun is None or env.sun is None:
            return env
        sun = env.sun.model_copy(
            update={"azimuth_deg": cand.sun[0], "elevation_deg": cand.sun[1], "frame": "world"}
        )
        return env.model_copy(update={"sun": sun})

    def scenario(self, cand: Candidate) -> Scenario:
        """Generate the candidate's trajectories (may raise ``InfeasibleScenario``)."""
        return self.family.generate(cand.params)

    def evaluate_many(self, cands: list[Candidate], threads: int = 2) -> list[Result]:
        """Evaluate candidates of this family (a batch; same values as ``evaluate``)."""
        if not cands:
            return []
        sun = np.array([[np.nan, np.nan] if c.sun is None else list(c.sun) for c in cands])
        d = Decoded(
            np.array([c.environment for c in cands]),
            sun,
            {p.name: np.array([c.params[p.name] for c in cands]) for p in self.family.space},
        )
        return self.results(cands, self.evaluate_decoded(d, threads))

    def evaluate(
        self, cand: Candidate, keep_trace: bool = False, collisions_only: bool = True
    ) -> Result:
        """Generate, evaluate and compute every metric (a batch of one). Without
        ``collisions_only`` the detection metrics are measured on an encounter without a
        collision too (``sensorgap evaluate`` shows them); with it, as the search stores
        them (0 there)."""
        sun = np.array([[np.nan, np.nan] if cand.sun is None else list(cand.sun)])
        d = Decoded(
            np.array([cand.environment]), sun, {k: np.array([v]) for k, v in cand.params.items()}
        )
        out = self.evaluate_decoded(d, collisions_only=collisions_only)
        r = self.results([cand], out)[0]
        if keep_trace and r.feasible:
            r.trace = self.evaluator.trace(
                self.scenario(cand), self.environment(cand), self.family.duration_s
            )
        return r
