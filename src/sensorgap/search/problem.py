"""A search problem: one family x environments, unit cube -> candidate -> metrics.

Dimensions: ``environment`` (choice of the given presets), then, with ``sun_search``,
``sun_azimuth_deg`` [0, 360) (world frame, clockwise from north, 1 deg steps) and
``sun_elevation_deg`` [2, 30] (1 deg steps) — applied only to environments whose preset has
a visible sun (others ignore them and record no sun) — then the family's parameters.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from sensorgap.config import EnvironmentConfig
from sensorgap.errors import InputError
from sensorgap.scenarios.family import Family, Param, ParamValue, Scenario
from sensorgap.scenarios.trajectory import InfeasibleScenario
from sensorgap.search.evaluate import Evaluator, Trace
from sensorgap.search.metrics import compute_all, metric_names

F64 = NDArray[np.float64]

SUN_AZIMUTH = Param("sun_azimuth_deg", 0.0, 359.0, unit="deg")
SUN_ELEVATION = Param("sun_elevation_deg", 2.0, 30.0, unit="deg")


def _canon(v: ParamValue) -> ParamValue:
    return v if isinstance(v, str) else float(f"{float(v):.6g}")


@dataclass(frozen=True)
class Candidate:
    """One point of the search: family, environment (+ sun), parameters."""

    family: str
    environment: str
    sun: tuple[float, float] | None
    params: dict[str, ParamValue]

    @property
    def scenario_id(self) -> str:
        """Stable 12-hex id of (family, environment, sun, parameters)."""
        text = json.dumps([self.family, self.environment, self.sun,
                           sorted(self.params.items())], sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:12]

    @property
    def environment_label(self) -> str:
        """``name`` or ``name@az/el`` with the world-frame sun."""
        if self.sun is None:
            return self.environment
        return f"{self.environment}@sun{self.sun[0]:g}/{self.sun[1]:g}"


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
    def score(self) -> float:
        """The ranking and search objective: log10 of the risk (-300 when infeasible)."""
        if not self.feasible:
            return -300.0
        return float(self.metrics.get("log10_risk", -300.0))


class SearchProblem:
    """Maps unit-cube vectors of one family to evaluated candidates."""

    def __init__(self, family: Family, environments: dict[str, EnvironmentConfig],
                 evaluator: Evaluator, sun_search: bool = True) -> None:
        if not environments:
            raise InputError("--environments", "", "give at least one environment")
        self.family = family
        self.environments = environments
        self.evaluator = evaluator
        self.env_names = tuple(environments)
        self.sun_search = sun_search and any(
            e.sun is not None and e.sun.visible for e in environments.values())
        dims = [Param("environment", choices=self.env_names)]
        if self.sun_search:
            dims += [SUN_AZIMUTH, SUN_ELEVATION]
        self.space: tuple[Param, ...] = (*dims, *family.space)
        self._n_env = len(dims)

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
            sun = (float(round(float(self.space[1].decode(float(u[1]))))),
                   float(round(float(self.space[2].decode(float(u[2]))))))
        params = {p.name: _canon(p.decode(float(v)))
                  for p, v in zip(self.family.space, u[self._n_env:], strict=True)}
        return Candidate(self.family.name, env, sun, params)

    def environment(self, cand: Candidate) -> EnvironmentConfig:
        """The environment of a candidate (the preset with its world-frame sun)."""
        env = self.environments[cand.environment]
        if cand.sun is None or env.sun is None:
            return env
        sun = env.sun.model_copy(update={"azimuth_deg": cand.sun[0],
                                         "elevation_deg": cand.sun[1], "frame": "world"})
        return env.model_copy(update={"sun": sun})

    def scenario(self, cand: Candidate) -> Scenario:
        """Generate the candidate's trajectories (may raise ``InfeasibleScenario``)."""
        return self.family.generate(cand.params)

    def evaluate(self, cand: Candidate, keep_trace: bool = False) -> Result:
        """Generate, evaluate and compute every metric."""
        try:
            sc = self.scenario(cand)
        except InfeasibleScenario as exc:
            return Result(cand, {m: 0.0 for m in metric_names()}, False, str(exc))
        tr = self.evaluator.trace(sc, self.environment(cand), self.family.duration_s)
        return Result(cand, compute_all(tr), True, "", tr if keep_trace else None)
