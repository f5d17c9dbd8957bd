"""Search strategies behind one ask/tell interface (the problem is separate, as in pymoo).

A strategy proposes points of the unit cube ``[0, 1]^d`` (``ask``) and is told the score of
each (``tell``); it knows nothing about scenarios. ``levels[i]`` is the number of choices
of dimension i (``None``: continuous), which grid search uses. Every random number comes
from the ``numpy.random.Generator`` passed in, so a seed fixes the whole run.
"""

from __future__ import annotations

import itertools
import math
from abc import ABC, abstractmethod
from typing import Any, ClassVar, TypeVar

import numpy as np
from numpy.typing import NDArray

from sensorgap.plugins import load_plugins
from sensorgap.registry import Registry

F64 = NDArray[np.float64]


class Strategy(ABC):
    """Base class: ``ask() -> (n, d)`` (n = 0 when done), ``tell(X, risk)``. A strategy's
    own keyword options are the parameters of its ``_configure`` (which calls the base's
    first), its batch size without one ``default_batch``."""

    name: ClassVar[str]
    description: ClassVar[str] = ""
    #: Batch size when the caller names none.
    default_batch: ClassVar[int] = 32
    #: ``batch_for``: the budget in about this many batches (generations) ...
    generations: ClassVar[int] = 1
    #: ... of at least and at most this many candidates each.
    batch_range: ClassVar[tuple[int, int]] = (1, 2048)

    def __init__(
        self,
        dim: int,
        levels: list[int | None],
        budget: int,
        rng: np.random.Generator,
        batch: int | None = None,
        **options: Any,
    ) -> None:
        self.dim, self.levels, self.budget, self.rng = dim, levels, budget, rng
        self.batch = max(1, self.default_batch if batch is None else batch)
        self.asked = 0
        self._configure(**options)

    def _configure(self, **options: Any) -> None:
        """The strategy's own options (keyword arguments of the constructor, set up after
        the common attributes); an option no strategy in the chain takes is a ValueError."""
        if options:
            raise ValueError(f"{self.name}: unknown options {', '.join(sorted(options))}")

    @classmethod
    def batch_for(cls, budget: int) -> int:
        """Batch size for a budget: ``budget // generations`` within ``batch_range``
        (candidates are evaluated a batch at a time, so larger batches are faster; the
        adaptive strategies take several generations, the others as few batches as the
        range allows)."""
        lo, hi = cls.batch_range
        return max(lo, min(hi, budget // cls.generations))

    def ask(self) -> F64:
        """The next batch (never beyond the budget)."""
        n = min(self.batch, self.budget - self.asked)
        if n <= 0:
            return np.empty((0, self.dim))
        X = self._propose(n)
        self.asked += len(X)
        return X

    @abstractmethod
    def _propose(self, n: int) -> F64:
        """Up to n new points."""

    def tell(self, X: F64, risk: F64) -> None:  # noqa: B027 - optional hook
        """Results of the last batch (default: ignored)."""


def latin_hypercube(rng: np.random.Generator, n: int, dim: int) -> F64:
    """``n`` points of the unit cube ``[0, 1]^dim`` (dimensionless), one in each of the
    ``n`` strata of every dimension (a random permutation of the strata per dimension, a
    uniform position inside each); ``(n, 0)`` when ``dim`` is 0."""
    cols = [(rng.permutation(n) + rng.random(n)) / n for _ in range(dim)]
    return np.column_stack(cols) if cols else np.empty((n, 0))


S = TypeVar("S", bound=type[Strategy])


_STRATEGIES: Registry[type[Strategy]] = Registry(
    "strategy", key=lambda c: c.name, on_lookup=load_plugins
)


def register_strategy(cls: S) -> S:
    """Class decorator: register a strategy under ``cls.name``."""
    return _STRATEGIES.register(cls)


def strategy_names() -> list[str]:
    """Registered strategy names, sorted."""
    return _STRATEGIES.names(sort=True)


def get_strategy(name: str) -> type[Strategy] | None:
    """The registered strategy, or ``None``."""
    return _STRATEGIES.get(name)


@register_strategy
class RandomSearch(Strategy):
    name = "random"
    description = "independent uniform samples"

    def _propose(self, n: int) -> F64:
        return self.rng.random((n, self.dim))


@register_strategy
class LatinHypercube(Strategy):
    name = "lhs"
    description = "Latin hypercube per batch (one sample per stratum and dimension)"

    def _propose(self, n: int) -> F64:
        return latin_hypercube(self.rng, n, self.dim)


@register_strategy
class GridSearch(Strategy):
    name = "grid"
    description = (
        "full factorial: every choice x k levels per continuous dimension, "
        "the largest k whose product fits the budget (cell centres)"
    )

    def _configure(self, **options: Any) -> None:
        super()._configure(**options)
        levels, budget = self.levels, self.budget
        fixed = math.prod(v for v in levels if v)
        n_cont = sum(1 for v in levels if not v)
        k = 1
        if n_cont:
            while fixed * (k + 1) ** n_cont <= budget:
                k += 1
        axes = [np.arange(v or k) for v in levels]
        self._points = [
            np.array([(i + 0.5) / (levels[d] or k) for d, i in enumerate(c)])
            for c in itertools.product(*axes)
        ]
        self.budget = min(budget, len(self._points))

    def _propose(self, n: int) -> F64:
        rows = self._points[self.asked : self.asked + n]
        return np.array(rows, dtype=np.float64).reshape(len(rows), self.dim)


@register_strategy
class CrossEntropy(Strategy):
    """Cross-entropy method: sample a Gaussian per dimension (clipped to the cube), keep the
    ``elite`` fraction with the highest risk, move mean and std towards them (smoothing
    ``alpha``), std never below ``min_std``. The first batch is a Latin hypercube."""

    name = "cem"
    description = "cross-entropy method (adaptive)"
    default_batch = 20
    generations = 40
    batch_range = (20, 500)

    def _configure(
        self, elite: float = 0.2, alpha: float = 0.7, min_std: float = 0.03, **options: Any
    ) -> None:
        super()._configure(**options)
        self.mean = np.full(self.dim, 0.5)
        self.std = np.full(self.dim, 0.35)
        self.elite, self.alpha, self.min_std = elite, alpha, min_std
        self._archive_x: list[F64] = []
        self._archive_f: list[float] = []

    def _propose(self, n: int) -> F64:
        if self.asked == 0:
            return latin_hypercube(self.rng, n, self.dim)
        X = self.mean + self.std * self.rng.standard_normal((n, self.dim))
        return np.clip(X, 0.0, 1.0)

    def tell(self, X: F64, risk: F64) -> None:
        self._archive_x.extend(X)
        self._archive_f.extend(float(r) for r in risk)
        # elite of everything seen so far (keeps the best even after a bad batch)
        n_elite = max(2, round(self.elite * self.batch))
        order = np.lexsort((np.arange(len(self._archive_f)), -np.asarray(self._archive_f)))
        elite = np.asarray(self._archive_x)[order[:n_elite]]
        self.mean = self.alpha * elite.mean(axis=0) + (1 - self.alpha) * self.mean
        self.std = np.maximum(
            self.alpha * elite.std(axis=0) + (1 - self.alpha) * self.std, self.min_std
        )


@register_strategy
class DifferentialEvolution(Strategy):
    """Differential evolution (Storn & Price 1997), DE/rand/1/bin, in ask/tell form: the
    first batch is a Latin hypercube population; each later batch is one trial vector per
    member, ``v = x_r1 + F (x_r2 - x_r3)`` crossed over with the member (rate ``cr``, one
    dimension always from ``v``), out-of-cube components reset between the member and the
    bound; a trial replaces its member when it scores at least as high. Chosen as the
    default when it beat CEM on the risk objective with point targets; on the collision
    objective with target bodies CEM does better (benchmarks/bench_search, docs/search.md).

    The crossover rate defaults to a low 0.2 (a trial changes about a fifth of the
    dimensions): the risk landscapes are partly separable (the sun position acts on the
    glare of whichever camera sees the target, whatever the trajectory), and on the
    benchmark's ten problems x ten seeds 0.2 won 89 comparisons against random search
    with ten times the evaluations, 0.9 won 81, with point targets and the risk objective;
    with target bodies and the collision objective DE wins 40 of 100, CEM 51
    (2026-11-26, docs/search.md)."""

    name = "de"
    description = "differential evolution (adaptive, multimodal)"
    default_batch = 40
    generations = 25  # the batch is the population: 20..200 members
    batch_range = (20, 200)

    def _configure(self, f: float = 0.7, cr: float = 0.2, **options: Any) -> None:
        super()._configure(**options)
        self.f, self.cr = f, cr
        self.pop: F64 | None = None
        self.fit: F64 | None = None

    def _propose(self, n: int) -> F64:
        if self.pop is None:
            return latin_hypercube(self.rng, n, self.dim)
        npop = len(self.pop)
        if npop < 4:  # too small for rand/1: random restarts
            return self.rng.random((n, self.dim))
        r = np.array([self.rng.choice(npop, 3, replace=False) for _ in range(npop)])
        v = self.pop[r[:, 0]] + self.f * (self.pop[r[:, 1]] - self.pop[r[:, 2]])
        low, high = v < 0.0, v > 1.0
        v = np.where(low, self.rng.random(v.shape) * self.pop, v)
        v = np.where(high, self.pop + self.rng.random(v.shape) * (1.0 - self.pop), v)
        mask = self.rng.random((npop, self.dim)) < self.cr
        mask[np.arange(npop), self.rng.integers(0, self.dim, npop)] = True
        return np.asarray(np.where(mask, v, self.pop)[:n], dtype=np.float64)

    def tell(self, X: F64, risk: F64) -> None:
        risk = np.asarray(risk, dtype=np.float64)
        if self.pop is None:
            self.pop, self.fit = np.array(X, dtype=np.float64), risk.copy()
            return
        assert self.fit is not None
        n = len(X)
        better = risk >= self.fit[:n]
        self.pop[:n][better] = X[better]
        self.fit[:n][better] = risk[better]
