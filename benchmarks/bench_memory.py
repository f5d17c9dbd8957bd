"""Memory benchmark (issue #7): a 1 km x 200 m coverage map at 0.05 m (80 M cells), System A,
car, clear, computed in tiles on 2 threads; wall time and the peak resident memory of the
process that computed it (a fresh child process, ``ru_maxrss``), against the 2 GiB limit.
``python benchmarks/run.py memory``."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from benchmarks.common import table

LIMIT_MIB = 2048.0
CHILD = r"""
import json, resource, time
from sensorgap.config import load_environment, load_target
from sensorgap.coverage import GridSpec, Scene, evaluate_grid
from sensorgap.models import Conditions, load_system
car = load_target("car")
scene = Scene(load_system("system_a"), car, Conditions.from_config(load_environment("clear")))
grid = GridSpec(-200.0, 800.0, -100.0, 100.0, 0.05, car.reference_height_m)
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
t0 = time.perf_counter()
cov = evaluate_grid(scene, grid, workers=2)
dt = time.perf_counter() - t0
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
print(json.dumps({"cells": grid.cells, "seconds": dt, "peak_mib": peak, "base_mib": base,
                  "result_mib": cov.fused.nbytes / 2**20,
                  "pd_max": float(cov.fused.max())}))
"""


def run() -> str:
    """Run the benchmark in a child process; returns the Markdown table."""
    src = str(Path(__file__).resolve().parents[1] / "src")
    out = subprocess.run(
        [sys.executable, "-c", CHILD],
        capture_output=True,
        check=True,
        env={"PYTHONPATH": src, "PATH": "/usr/bin:/bin"},
        timeout=1800,
    )
    r = json.loads(out.stdout.decode().strip().splitlines()[-1])
    rows = [
        [
            f"{r['cells']:,}",
            f"{r['seconds']:.1f}",
            f"{r['result_mib']:.0f}",
            f"{r['base_mib']:.0f}",
            f"{r['peak_mib']:.0f}",
            f"{r['peak_mib'] / LIMIT_MIB:.2f}",
            "yes" if r["peak_mib"] <= LIMIT_MIB else "no",
        ]
    ]
    return (
        "Coverage map 1000 m x 200 m at 0.05 m, System A, car, clear, 2 threads, tiles "
        "of 400,000 cells\n\n"
        + table(
            [
                "cells",
                "time [s]",
                "result array [MiB]",
                "process before [MiB]",
                "peak [MiB]",
                "peak / 2 GiB",
                "<= 2 GiB",
            ],
            rows,
        )
        + "\n"
    )


if __name__ == "__main__":
    print(run())
