"""The search loop: per family, ``seeds`` independent strategies ask for candidates,
the executor evaluates them, the strategies are told the objective. No file is read or
written here: stored results come in and new ones go out through callbacks (the run's
SQLite store in ``search.run``; none for a search kept in memory).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from sensorgap.search.executors import Executor
from sensorgap.search.problem import Result
from sensorgap.search.settings import Prepared
from sensorgap.search.strategies import get_strategy

#: A stored result of (family, evaluation index, scenario id), or ``None``.
Cached = Callable[[str, int, str], Result | None]
#: Receives (evaluation index in its family, result) pairs of a freshly evaluated batch.
Keep = Callable[[list[tuple[int, Result]]], None]


@dataclass
class LoopResult:
    """Every result in evaluation order, which of the independent searches each belongs
    to (0 .. seeds - 1), and how many were evaluated or taken from the store."""

    results: list[Result] = field(default_factory=list)
    stream: list[int] = field(default_factory=list)
    evaluated: int = 0
    reused: int = 0


def search_loop(
    p: Prepared,
    runner: Executor,
    cached: Cached | None = None,
    keep: Keep | None = None,
    progress: Callable[[int], None] | None = None,
) -> LoopResult:
    """Run the budget: family i's share as ``seeds`` searches with random streams
    ``[seed, i]`` (the one-seed search's) and ``[seed, i, s]`` for s = 1.., each with its
    part of the share. A candidate ``cached`` returns is not evaluated again (resume);
    ``keep`` receives the fresh ones, ``progress`` the count of each batch."""
    s = p.settings
    strat_cls = get_strategy(s.strategy)
    assert strat_cls is not None  # checked by SearchSettings.check
    out = LoopResult()
    for i, (fam, share) in enumerate(zip(p.families, p.shares(), strict=True)):
        prob = p.problems[fam.name]
        idx = 0
        for s_i in range(s.seeds):
            part = share // s.seeds + (1 if s_i < share % s.seeds else 0)
            strat = strat_cls(
                prob.dim,
                prob.levels,
                part,
                np.random.default_rng([s.seed, i] if s_i == 0 else [s.seed, i, s_i]),
                batch=strat_cls.batch_for(part),
            )
            while len(X := strat.ask()):
                decoded = prob.decode_batch(X)
                cands = prob.candidates(decoded)
                batch: list[Result | None] = [
                    None if cached is None else cached(fam.name, idx + j, c.scenario_id)
                    for j, c in enumerate(cands)
                ]
                todo = np.array([j for j, r in enumerate(batch) if r is None], dtype=int)
                out.reused += len(batch) - todo.size
                if todo.size:
                    fresh = prob.results(
                        [cands[j] for j in todo], runner.evaluate(p.spec, prob, decoded.take(todo))
                    )
                    for j, r in zip(todo.tolist(), fresh, strict=True):
                        batch[j] = r
                    if keep is not None:
                        keep([(idx + j, fresh[k]) for k, j in enumerate(todo.tolist())])
                    out.evaluated += todo.size
                done = [r for r in batch if r is not None]
                strat.tell(X, np.array([r.objective for r in done]))
                out.results.extend(done)
                out.stream.extend([s_i] * len(done))
                idx += len(done)
                if progress is not None:
                    progress(len(done))
    return out
