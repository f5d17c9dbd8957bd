"""Search benchmark: candidates/s for 10 s scenarios at 20 Hz with the coverage-map lookup
and with exact point evaluation, the lookup's error on the risk and on the top 10, and the
adaptive strategy (CEM) against random search with 10x its evaluations.
Setup: System B, family ``slow_ahead_curve`` (motorway curve), environments fog_50 and
clear (sun searched)."""

from __future__ import annotations

import time

import numpy as np

from benchmarks.common import table
from sensorgap.config import load_environments
from sensorgap.models import load_system
from sensorgap.scenarios import load_family
from sensorgap.search.evaluate import Evaluator
from sensorgap.search.problem import Result, SearchProblem
from sensorgap.search.strategies import get_strategy

N_SPEED = 200
N_ADAPTIVE = 60


def _problem(mode: str) -> SearchProblem:
    envs = load_environments()
    return SearchProblem(load_family("slow_ahead_curve"),
                         {"fog_50": envs["fog_50"], "clear": envs["clear"]},
                         Evaluator(load_system("system_b"), mode))


def _search(prob: SearchProblem, name: str, budget: int, seed: int) -> list[Result]:
    cls = get_strategy(name)
    assert cls is not None
    s = cls(prob.dim, prob.levels, budget, np.random.default_rng(seed))
    out: list[Result] = []
    while len(X := s.ask()):
        rs = [prob.evaluate(prob.decode(u)) for u in X]
        s.tell(X, np.array([r.score for r in rs]))
        out.extend(rs)
    return out


def run() -> str:
    """Run the benchmark; returns the Markdown tables."""
    rng = np.random.default_rng(0)
    U = rng.random((N_SPEED, _problem("lookup").dim))
    rows, risks = [], {}
    for mode in ("lookup", "exact"):
        prob = _problem(mode)
        prob.evaluate(prob.decode(U[0]))  # warm-up: maps, numba, scenes
        t0 = time.perf_counter()
        res = [prob.evaluate(prob.decode(u)) for u in U]
        dt = time.perf_counter() - t0
        risks[mode] = res
        rows.append([mode, f"{N_SPEED / dt:.0f}", f"{1e3 * dt / N_SPEED:.1f}"])
    look = np.array([r.risk for r in risks["lookup"]])
    exact = np.array([r.risk for r in risks["exact"]])
    top_l = set(np.argsort(-look, kind="stable")[:10].tolist())
    top_e = set(np.argsort(-exact, kind="stable")[:10].tolist())
    err = [["max abs risk error", f"{np.max(np.abs(look - exact)):.2e}"],
           ["mean abs risk error", f"{np.mean(np.abs(look - exact)):.2e}"],
           ["top-10 overlap (lookup vs exact)", f"{len(top_l & top_e)}/10"],
           ["max exact risk", f"{exact.max():.4f}"]]
    prob = _problem("lookup")
    adapt = []
    for seed in (1, 2, 3, 4, 5):
        cem = _search(prob, "cem", N_ADAPTIVE, seed)
        rnd = _search(prob, "random", 10 * N_ADAPTIVE, seed)
        best_cem, best_rnd = max(r.risk for r in cem), max(r.risk for r in rnd)
        adapt.append([str(seed), f"{best_cem:.4f} ({max(r.score for r in cem):.1f})",
                      f"{best_rnd:.4f} ({max(r.score for r in rnd):.1f})",
                      "yes" if best_cem >= best_rnd else "no"])
    return ("Search: System B, slow_ahead_curve, fog_50 + clear (sun searched), 10 s at "
            f"20 Hz (201 steps), {N_SPEED} random candidates\n\n"
            + table(["Pd evaluation", "candidates/s", "ms/candidate"], rows) + "\n\n"
            + table(["lookup vs exact", "value"], err) + "\n\n"
            + table(["seed", f"best risk (log10) CEM, {N_ADAPTIVE} evals",
                     f"best risk (log10) random, {10 * N_ADAPTIVE} evals", "CEM >= random"],
                    adapt)
            + "\n")


if __name__ == "__main__":
    print(run())
