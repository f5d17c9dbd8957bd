"""Scale-out benchmark (issue #7): a search's candidate evaluation on Dask distributed with 1
and 2 local worker processes (one thread each), candidates/s and the speed-up, same run.
``python benchmarks/run.py dask [--candidates N]`` (default 1,000,000).

Setup: System A, families cut_in_left + slow_ahead_curve + crossing_pedestrian, all
environment presets, sun searched, lookup maps; random candidates in batches of 60,000.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from benchmarks.common import table
from sensorgap.config import load_environments
from sensorgap.search.executors import DaskExecutor, ProblemSpec, problems_for

N_DEFAULT = 1_000_000
BATCH = 60_000
FAMILIES = ("cut_in_left", "slow_ahead_curve", "crossing_pedestrian")


def _rate(spec: ProblemSpec, workers: int, n: int) -> float:
    problems = problems_for(spec)
    rng = np.random.default_rng(0)
    with DaskExecutor(None, workers) as ex:
        for prob in problems.values():  # warm-up: maps and numba in every worker
            ex.evaluate(spec, prob, prob.decode_batch(rng.random((256 * workers, prob.dim))))
        t0 = time.perf_counter()
        done = 0
        while done < n:
            for fam in FAMILIES:
                prob = problems[fam]
                k = min(BATCH, n - done)
                if k <= 0:
                    break
                ex.evaluate(spec, prob, prob.decode_batch(rng.random((k, prob.dim))))
                done += k
        return n / (time.perf_counter() - t0)


def run(n: int = N_DEFAULT) -> str:
    """Run the benchmark; returns the Markdown table."""
    spec = ProblemSpec(
        "system_a", FAMILIES, tuple(load_environments()), None, "lookup", "cumulative", True
    )
    r1 = _rate(spec, 1, n)
    r2 = _rate(spec, 2, n)
    rows = [
        ["1", f"{r1:,.0f}", f"{n / r1:.1f}", "1.00x"],
        ["2", f"{r2:,.0f}", f"{n / r2:.1f}", f"{r2 / r1:.2f}x"],
    ]
    return (
        f"Dask distributed, local cluster, {n:,} candidates (System A, "
        f"{', '.join(FAMILIES)}, 7 environments, 10 s at 20 Hz); target speed-up >= 1.7x"
        "\n\n" + table(["workers", "candidates/s", "time [s]", "speed-up"], rows) + "\n"
    )


if __name__ == "__main__":
    args = sys.argv[1:]
    n = int(args[args.index("--candidates") + 1]) if "--candidates" in args else N_DEFAULT
    print(run(n))
