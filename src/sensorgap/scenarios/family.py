"""Scenario families: a generator kind (Python) + a typed parameter space (TOML).

A *kind* (``FamilyKind`` subclass, registered by name) knows how to turn parameters into an
ego and a target trajectory on a road. A *family* is a kind with its settings (road, lanes,
target class, duration) and parameter ranges, loaded from ``templates/scenarios/<name>.toml``
(see ``sensorgap.scenarios.loader``); families are selected by that name.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar, TypeVar

import numpy as np
from numpy.typing import NDArray

from sensorgap.plugins import load_plugins
from sensorgap.registry import Registry
from sensorgap.roads import RoadNetwork
from sensorgap.scenarios.trajectory import LIMITS, Limits, Trajectory

F64 = NDArray[np.float64]
ParamValue = float | str


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

    def corners(self) -> tuple[ParamValue, ...]:
        """Extreme values (for the fit check): both ends, or every choice."""
        return self.choices if self.choices else (self.low, self.high)


@dataclass(frozen=True)
class Scenario:
    """Generated trajectories: ego (rear axle) and target (centre), same time axis."""

    ego: Trajectory
    target: Trajectory
    target_class: str


class FamilyKind(ABC):
    """A parameterised generator of ego and target trajectories.

    Subclasses set ``name``, ``settings`` (setting -> default, ``None`` = required) and
    ``parameters`` (the default space; a TOML family narrows or replaces ranges) and
    implement ``generate``. Register with ``@register_kind``.
    """

    name: ClassVar[str]
    description: ClassVar[str] = ""
    settings: ClassVar[dict[str, Any]] = {}
    parameters: ClassVar[tuple[Param, ...]] = ()

    @abstractmethod
    def generate(self, family: Family, p: Mapping[str, ParamValue],
                 net: RoadNetwork) -> Scenario:
        """Trajectories for parameters ``p``; ``InfeasibleScenario`` if they are not
        feasible, ``InputError`` (from the road layer) if they leave the road."""


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
    _names: tuple[str, ...] = field(default=(), repr=False)

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
        """Feasibility bounds for the target class."""
        return LIMITS.get(self.target_class, LIMITS["car"])

    def decode(self, u: F64) -> dict[str, ParamValue]:
        """Unit-cube vector (one entry per parameter) -> parameters."""
        return {p.name: p.decode(float(v)) for p, v in zip(self.space, u, strict=True)}

    def generate(self, params: Mapping[str, ParamValue]) -> Scenario:
        """Generate and check feasibility (target limits; ego with car limits)."""
        sc = self.kind.generate(self, params, self.network)
        sc.ego.check(LIMITS["car"], "ego")
        sc.target.check(self.limits, "target")
        return sc

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


# -- registries --------------------------------------------------------------------------
K = TypeVar("K", bound=type[FamilyKind])


_KINDS: Registry[type[FamilyKind]] = Registry("family kind", key=lambda c: c.name,
                                        on_lookup=load_plugins)


def register_kind(cls: K) -> K:
    """Class decorator: register a family kind under ``cls.name``."""
    return _KINDS.register(cls)


def kind_names() -> list[str]:
    """Registered family kind names, sorted."""
    return _KINDS.names(sort=True)


def get_kind(name: str) -> type[FamilyKind] | None:
    """The registered family kind, or ``None``."""
    return _KINDS.get(name)


def registry_snapshot() -> Mapping[str, Callable[..., Any]]:
    """Read-only view of the kinds (for docs and tests)."""
    return _KINDS.snapshot()
