"""Default-job benchmark (issue #13): ``make run``'s main job (System A, every family and
environment, 100,000 candidates as 3 independent searches, coverage, near and far field,
export, report) in a fresh child process per run, 3 runs: the median wall time and the
peak memory against the targets (60 s, 1.5 GiB on 2 cores).

Time: the job's own total (``jobs.run_default``: its stages, start-up of the child
excluded) and the child's wall time (start-up and imports included). Memory: the job's own
figure (this process's peak plus the coverage process's peak, an upper bound since the two
need not coincide) and the process tree's resident memory sampled every 0.1 s.
``python benchmarks/run.py job``.
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.common import load_average, table
from sensorgap.jobs import TARGET_PEAK_MIB, TARGET_TIME_S

RUNS = 3
CHILD = r"""
import json, sys
from pathlib import Path
from sensorgap.jobs import run_default
from sensorgap.runtime import tune_allocator
tune_allocator()
info = run_default(Path(sys.argv[1]))
print(json.dumps({"total_s": info["total_s"], "peak_rss_mib": info["peak_rss_mib"]}))
"""


def _tree_rss_mib(root: int) -> float:
    """Resident memory of process ``root`` and its descendants now, MiB (Linux /proc)."""
    parents: dict[int, int] = {}
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                with open(f"/proc/{d}/stat", encoding="ascii", errors="replace") as f:
                    parents[int(d)] = int(f.read().rsplit(")", 1)[1].split()[1])
            except (OSError, ValueError, IndexError):
                continue
    tree, grew = {root}, True
    while grew:
        kids = {p for p, pp in parents.items() if pp in tree and p not in tree}
        tree |= kids
        grew = bool(kids)
    kib = 0
    for pid in tree:
        try:
            with open(f"/proc/{pid}/status", encoding="ascii", errors="replace") as f:
                kib += next((int(x.split()[1]) for x in f if x.startswith("VmRSS:")), 0)
        except OSError:
            continue
    return kib / 1024.0


def _one(out: Path) -> dict[str, float]:
    """One default job in a fresh child: its own total and peak, the child's wall time and
    the sampled peak of its process tree."""
    src = str(Path(__file__).resolve().parents[1] / "src")
    env = {**os.environ, "PYTHONPATH": src}
    t0 = time.perf_counter()
    child = subprocess.Popen(
        [sys.executable, "-c", CHILD, str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        env=env,
    )
    sampled = 0.0
    while child.poll() is None:
        sampled = max(sampled, _tree_rss_mib(child.pid))
        time.sleep(0.1)
    wall = time.perf_counter() - t0
    assert child.stdout is not None
    lines = child.stdout.read().decode().strip().splitlines()
    if child.returncode != 0 or not lines:
        raise RuntimeError(f"the default job failed (exit {child.returncode})")
    r = json.loads(lines[-1])
    return {
        "total_s": float(r["total_s"]),
        "wall_s": wall,
        "peak_mib": float(r["peak_rss_mib"]),
        "sampled_mib": sampled,
    }


def run(runs: int = RUNS) -> str:
    """Run the benchmark; returns the Markdown table."""
    load_start = load_average()
    results = []
    for i in range(runs):
        with tempfile.TemporaryDirectory() as tmp:
            results.append(_one(Path(tmp) / f"run{i}"))
    load_end = load_average()

    def cell(key: str, fmt: str) -> str:
        vals = [r[key] for r in results]
        return f"{statistics.median(vals):{fmt}} ({' / '.join(f'{v:{fmt}}' for v in vals)})"

    total = statistics.median(r["total_s"] for r in results)
    peak = max(r["peak_mib"] for r in results)
    rows = [
        [
            "job's own total [s]",
            cell("total_s", ".1f"),
            f"{TARGET_TIME_S:.0f}",
            _met(total <= TARGET_TIME_S),
        ],
        ["child's wall time, start-up included [s]", cell("wall_s", ".1f"), "", ""],
        [
            "job's own peak, both processes added [MiB]",
            cell("peak_mib", ".0f"),
            f"{TARGET_PEAK_MIB:.0f}",
            _met(peak <= TARGET_PEAK_MIB),
        ],
        ["process tree sampled every 0.1 s [MiB]", cell("sampled_mib", ".0f"), "", ""],
    ]
    return (
        f"Default job (System A, every family and environment, 100,000 candidates), {runs} "
        "runs in fresh child processes: median (each run)\n\n"
        + table(["quantity", "median (runs)", "target", "met"], rows)
        + f"\n\nLoad average (1 min) {load_start} before, {load_end} after "
        f"({os.cpu_count()} CPUs); time is met on the median, memory on the largest run.\n"
    )


def _met(ok: bool) -> str:
    return "yes" if ok else "no"


if __name__ == "__main__":
    print(run(int(sys.argv[1]) if len(sys.argv) > 1 else RUNS))
