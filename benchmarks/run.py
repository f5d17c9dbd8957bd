"""Run sensorgap's benchmarks and print their tables: ``python benchmarks/run.py [name...]``.

Every ratio is measured in the same run on the same machine; nothing is compared against
numbers typed in from elsewhere.
"""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

BENCHMARKS = {
    "coverage": "benchmarks.bench_coverage",
    "search": "benchmarks.bench_search",
    "dask": "benchmarks.bench_dask",
    "memory": "benchmarks.bench_memory",
    "tradeoff": "benchmarks.bench_tradeoff",
    "limits": "benchmarks.bench_limits",
    "corpus": "benchmarks.bench_corpus",
    "job": "benchmarks.bench_job",
}


def main(argv: list[str]) -> int:
    from sensorgap.runtime import tune_allocator

    tune_allocator()  # as the command line does (sensorgap.runtime)
    names = [a for a in argv if not a.startswith("--") and not a.isdigit()] or list(BENCHMARKS)
    unknown = [n for n in names if n not in BENCHMARKS]
    if unknown:
        print(
            f"unknown benchmark(s): {', '.join(unknown)}; have: {', '.join(BENCHMARKS)}",
            file=sys.stderr,
        )
        return 2
    for name in names:
        module = importlib.import_module(BENCHMARKS[name])
        print(f"## {name}\n")
        print(module.run())
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
