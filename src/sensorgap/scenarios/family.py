"""Scenario families: a generator kind (Python) + a typed parameter space (TOML).

A *kind* (``FamilyKind`` subclass, registered by name) knows how to turn parameters into an
ego and a target trajectory on a road. A *family* is a kind with its settings (road, lanes,
target class, duration) and parameter ranges, loaded from ``templates/scenarios/<name>.toml``
(see ``sensorgap.scenarios.loader``); families are selected by that name.
"""

from __future__ import annotations

import math
from abc import ABC
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any, ClassVar, TypeVar

import numpy as np
from numpy.typing import NDArray

from sensorgap.config.target import TargetConfig
from sensorgap.plugins import load_plugins
from sensorgap.registry import Registry
from sensorgap.roads import RoadNetwork
from sensorgap.scenarios.batch import (
    LaneTable,
    Scenario,
    ScenarioBatch,
    Tracks,
    check_tracks,
)
from sensorgap.scenarios.trajectory import LIMITS, InfeasibleScenario, Limits, OffRoad

F64 = NDArray[np.float64]
ParamValue = float | str
#: Parameter columns of a batch: name -> (B,) float64 values, or (B,) str for choices.
Columns = Mapping[str, NDArray[Any]]


@dataclass(frozen=True)
class Param:
    """One search dimension: a continuous range ``[low, high]`` or a list of ``choices``."""

    name: str
    low: float = 0.0
    high: float = 0.0
    choices: tuple[str, ...] = ()
    unit: str = ""

    @property
    def categorical(self) -> bool:
        """Whether the dimension is a choice."""
        return bool(self.choices)

    def decode(self, u: float) -> ParamValue:
        """Unit interval [0, 1] -> value (choices: equal-width bins)."""
        u = min(max(float(u), 0.0), 1.0)
        if self.choices:
            return self.choices[min(int(u * len(self.choices)), len(self.choices) - 1)]
        return self.low + u * (self.high - self.low)

    def encode(self, value: ParamValue) -> float:
        """Value -> unit interval (choices: centre of the bin); inverse of ``decode``."""
        if self.choices:
            return (self.choices.index(str(value)) + 0.5) / len(self.choices)
        return (float(value) - self.low) / (self.high - self.low)

    def from_json(self, v: object) -> ParamValue:
        """A value as a ranking file holds it: a choice by name, else a finite JSON number
        (not a boolean, not a string); anything else -> ``ValueError`` saying what is
        expected."""
        if self.choices:
            if not isinstance(v, str) or v not in self.choices:
                raise ValueError(f"expected one of {', '.join(self.choices)}, got {str(v)[:40]!r}")
            return v
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise ValueError(f"expected a finite number, got {str(v)[:40]!r}")
        return float(v)

    def corners(self) -> tuple[ParamValue, ...]:
        """Extreme values (for the fit check): both ends, or every choice."""
        return self.choices if self.choices else (self.low, self.high)


class FamilyKind(ABC):
    """A parameterised generator of ego and target trajectories.

    Subclasses set ``name``, ``settings`` (setting -> default, ``None`` = required) and
    ``parameters`` (the default space; a TOML family narrows or replaces ranges) and
    implement ``generate_batch`` (fast: B parameter vectors at once, the built-in kinds) or
    ``generate`` (one at a time; the batch default loops over it). Register with
    ``@register_kind``.
    """

    name: ClassVar[str]
    description: ClassVar[str] = ""
    settings: ClassVar[dict[str, Any]] = {}
    parameters: ClassVar[tuple[Param, ...]] = ()
    #: True for kinds whose history before t = 0 continues their start unchanged (a slower
    #: car ahead, both at constant speed in one lane): the search then uses only
    #: encounters whose target starts beyond every confirming sensor's reach, so no
    #: chance to detect it falls before t = 0, where the simulation begins
    #: (``search.possible``).
    start_out_of_reach: ClassVar[bool] = False

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if (
            getattr(cls, "name", None)
            and cls.generate is FamilyKind.generate
            and cls.generate_batch is FamilyKind.generate_batch
        ):
            raise TypeError(f"family kind {cls.__name__} must implement generate_batch or generate")

    def generate(self, family: Family, p: Mapping[str, ParamValue], net: RoadNetwork) -> Scenario:
        """Trajectories for parameters ``p``; ``InfeasibleScenario`` (``OffRoad`` when they
        leave the road) if they are not feasible. Default: a batch of one."""
        cols = {k: np.array([v]) for k, v in p.items()}
        b = self.generate_batch(family, cols, net)
        if not b.ok[0]:
            assert b.offroad is not None
            raise (OffRoad if b.offroad[0] else InfeasibleScenario)(b.notes[0])
        return b.scenario(0)

    def generate_batch(self, family: Family, cols: Columns, net: RoadNetwork) -> ScenarioBatch:
        """Trajectories for B parameter vectors (columns); infeasible rows are marked in
        the batch. Default: one ``generate`` call per row."""
        n = len(next(iter(cols.values()))) if cols else 1
        rows: list[Scenario | None] = []
        notes = [""] * n
        off = np.zeros(n, dtype=bool)
        for i in range(n):
            try:
                rows.append(self.generate(family, {k: _scalar(v[i]) for k, v in cols.items()}, net))
            except InfeasibleScenario as exc:
                rows.append(None)
                notes[i] = str(exc)
                off[i] = isinstance(exc, OffRoad)
        ok = np.array([r is not None for r in rows], dtype=bool)
        good = next((r for r in rows if r is not None), None)
        t = good.ego.t if good is not None else np.arange(2, dtype=np.float64)

        def stack(who: str) -> Tracks:
            arrs = []
            for r in rows:
                tr = getattr(r, who) if r is not None else None
                arrs.append(
                    [
                        np.zeros(len(t)) if tr is None else getattr(tr, a)
                        for a in ("x", "y", "heading", "speed")
                    ]
                )
            return Tracks(*(np.array([a[j] for a in arrs]).reshape(n, len(t)) for j in range(4)))

        return ScenarioBatch(t, stack("ego"), stack("target"), ok, notes, family.target_class, off)


@dataclass
class Family:
    """A kind with settings and its parameter space (loaded from TOML)."""

    name: str
    kind: FamilyKind
    settings: dict[str, Any]
    space: tuple[Param, ...]
    network: RoadNetwork
    source: str = ""
    description: str = ""
    #: the target class's largest speed, m/s (``max_speed_m_s`` of the targets file the
    #: family was loaded with); None: the class's default in ``trajectory.LIMITS``
    max_speed_m_s: float | None = None
    #: the occluder class's config (``settings['occluder']``) in the targets file the
    #: family was loaded with (a run's recorded copy); None: no occluder, or a family made
    #: in code (``scenarios.occluded.occluder_class`` then reads the shipped classes)
    occluder: TargetConfig | None = None
    #: the target class's config in that targets file (None: a family made in code)
    target_config: TargetConfig | None = None
    _names: tuple[str, ...] = field(default=(), repr=False)
    _tables: dict[tuple[str, int], LaneTable] = field(default_factory=dict, repr=False)

    @property
    def target_class(self) -> str:
        """Target class name (``targets.toml``)."""
        return str(self.settings["target"])

    @property
    def duration_s(self) -> float:
        """Scenario duration, s."""
        return float(self.settings["duration_s"])

    @property
    def limits(self) -> Limits:
        """Feasibility bounds for the target class: its accelerations from
        ``trajectory.LIMITS`` (a class it does not name: a car's), its largest speed from
        the targets file (``max_speed_m_s``: it was ignored, hostile round 22)."""
        base = LIMITS.get(self.target_class, LIMITS["car"])
        if self.max_speed_m_s is None:
            return base
        return replace(base, max_speed=float(self.max_speed_m_s))

    def decode(self, u: F64) -> dict[str, ParamValue]:
        """Unit-cube vector (one entry per parameter) -> parameters."""
        return {p.name: p.decode(float(v)) for p, v in zip(self.space, u, strict=True)}

    def generate(self, params: Mapping[str, ParamValue]) -> Scenario:
        """Generate and check feasibility (target limits; ego with car limits); a batch of
        one, so identical to the corresponding row of ``generate_batch``."""
        b = self.generate_batch({k: np.array([v]) for k, v in params.items()})
        if not b.ok[0]:
            assert b.offroad is not None
            raise (OffRoad if b.offroad[0] else InfeasibleScenario)(b.notes[0])
        return b.scenario(0)

    def generate_batch(self, cols: Columns) -> ScenarioBatch:
        """Generate B scenarios (parameter columns) and check feasibility per row."""
        b = self.kind.generate_batch(self, cols, self.network)
        b.start_out_of_reach = self.kind.start_out_of_reach
        for who, tracks, limits in (
            ("ego", b.ego, LIMITS["car"]),
            ("target", b.target, self.limits),
        ):
            bad, notes = check_tracks(tracks, b.t, limits, who)
            b.reject(bad, notes)
        return b

    def lane_table(self, road_id: str, lane: int) -> LaneTable:
        """The (cached) sampled centre line of a lane."""
        key = (road_id, lane)
        tab = self._tables.get(key)
        if tab is None:
            tab = self._tables[key] = LaneTable(self.network, road_id, lane)
        return tab

    def distance(self, a: Mapping[str, ParamValue], b: Mapping[str, ParamValue]) -> float:
        """Normalised parameter distance: RMS over dimensions of the range-scaled difference
        (continuous) or 0/1 mismatch (choices); 0 = identical, 1 = opposite corners."""
        acc = 0.0
        for p in self.space:
            if p.categorical:
                acc += 0.0 if a[p.name] == b[p.name] else 1.0
            else:
                acc += (p.encode(a[p.name]) - p.encode(b[p.name])) ** 2
        return math.sqrt(acc / max(1, len(self.space)))


def _scalar(v: Any) -> ParamValue:
    return str(v) if isinstance(v, str | np.str_) else float(v)


# -- registries --------------------------------------------------------------------------
K = TypeVar("K", bound=type[FamilyKind])


_KINDS: Registry[type[FamilyKind]] = Registry(
    "family kind", key=lambda c: c.name, on_lookup=load_plugins
)


def register_kind(cls: K) -> K:
    """Class decorator: register a family kind under ``cls.name``."""
    return _KINDS.register(cls)


def kind_names() -> list[str]:
    """Registered family kind names, sorted."""
    return _KINDS.names(sort=True)


def get_kind(name: str) -> type[FamilyKind] | None:
    """The registered family kind, or ``None``."""
    return _KINDS.get(name)
