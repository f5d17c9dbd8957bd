"""Input-limit benchmark (issue #18): the worst input each documented limit accepts
(docs/limits.md), run through the command line in a fresh child process each; wall time
and the child's peak resident memory (``resource.getrusage(RUSAGE_SELF).ru_maxrss``),
against the 4 GiB budget. ``python benchmarks/run.py limits`` (all at the limits: minutes
and several GiB, run it on a quiet machine) or ``python benchmarks/bench_limits.py
--quick`` (each case scaled down 10x in size: seconds, a smoke test of the harness).

Every case must finish with exit code 0; the table says whether the peak stayed within
the budget.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "src"))

from benchmarks.common import table  # noqa: E402
from sensorgap import cli  # noqa: E402
from sensorgap.config.vehicle import MAX_SENSORS  # noqa: E402
from sensorgap.coverage import limits  # noqa: E402
from sensorgap.coverage.pointsio import MAX_POINT_SENSOR_VALUES, MAX_POINTS  # noqa: E402
from sensorgap.roads.opendrive import MAX_GEOMETRIES  # noqa: E402
from sensorgap.search.corridor import MAX_CORRIDOR_NODES  # noqa: E402
from sensorgap.search.settings import MAX_BUDGET  # noqa: E402

BUDGET_MIB = 4096.0
SYSTEM_A_SENSORS = 23
CHILD = r"""
import json, resource, sys, time
from sensorgap.cli import main
t0 = time.perf_counter()
code = main(sys.argv[1:])
dt = time.perf_counter() - t0
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
print(json.dumps({"exit": code, "seconds": dt, "peak_mib": peak}))
"""


@dataclass
class Case:
    """One worst accepted input: a name, the limit it sits at, and how to build its argv
    (given a scratch folder and the size scale, 1.0 = at the limit)."""

    name: str
    limit: str
    argv: Callable[[Path, float], list[str]]


def _car_in_clear(command: str) -> list[str]:
    """The start of a command line that evaluates a car for System A in clear air."""
    return [command, "--vehicle", "system_a", "--environment", "clear", "--target", "car"]


def _coverage(tmp: Path, scale: float) -> list[str]:
    cells = limits.MAX_GRID_CELLS * scale
    ny = 1000
    nx = int(cells // ny)  # 0.1 m cells: nx * ny <= the limit
    return [
        *_car_in_clear("coverage"),
        "--resolution",
        "0.1",
        f"--extent=-10,{-10 + nx * 0.1:g},-50,50",
        "--out",
        str(tmp / "cov"),
    ]


def _body_map(cells: float, occluders: int, out: Path) -> list[str]:
    """System A's car bodies on a square of about ``cells`` cells of 0.1 m round the
    vehicle, behind ``occluders`` trucks standing in a block ahead (10 a row)."""
    half = int(math.sqrt(cells)) * 0.05
    argv = [*_car_in_clear("coverage"), "--resolution", "0.1", "--heading", "0"]
    argv.append(f"--extent=-{half:g},{half:g},-{half:g},{half:g}")
    for i in range(occluders):
        argv += ["--occluder", f"truck@{20 + (i % 10) * 15},{-40 + (i // 10) * 9},0"]
    return [*argv, "--out", str(out)]


def _coverage_bodies(tmp: Path, scale: float) -> list[str]:
    return _body_map(limits.MAX_BODY_CELLS * scale, 0, tmp / "body")


def _coverage_occluded(tmp: Path, scale: float) -> list[str]:
    """System A's bodies behind the most occluders, over as many cells as the work limit
    then allows (``limits.MAX_BODY_WORK``)."""
    n = limits.MAX_OCCLUDERS
    cells = limits.MAX_BODY_WORK * scale / (SYSTEM_A_SENSORS * (1 + n * limits.OCCLUDER_WORK))
    return _body_map(cells, n, tmp / "occluded")


def _coverage_per_sensor(tmp: Path, scale: float) -> list[str]:
    cells = limits.MAX_PER_SENSOR_CELLS * scale / SYSTEM_A_SENSORS
    nx = int(cells // 1000)
    return [
        *_car_in_clear("coverage"),
        "--resolution",
        "0.1",
        f"--extent=-10,{-10 + nx * 0.1:g},-50,50",
        "--per-sensor",
        "--out",
        str(tmp / "per"),
    ]


def _nearfield(tmp: Path, scale: float) -> list[str]:
    lo = cli.NEARFIELD_RESOLUTION_M[0]
    return [
        "nearfield",
        "--vehicle",
        "system_a",
        "--resolution",
        f"{lo / math.sqrt(scale):g}",
        "--out",
        str(tmp / "nf"),
    ]


def _probe(tmp: Path, scale: float) -> list[str]:
    n = int(min(MAX_POINTS, MAX_POINT_SENSOR_VALUES // SYSTEM_A_SENSORS) * scale)
    pts = tmp / "points.csv"
    with pts.open("w") as f:
        f.write("x,y\n")
        for i in range(n):
            f.write(f"{(i % 2000) * 0.1 - 50:.1f},{(i // 2000) % 100 * 0.5 - 25:.1f}\n")
    return [
        *_car_in_clear("probe"),
        "--points",
        str(pts),
        "--out",
        str(tmp / "probe.csv"),
    ]


def _corridor(tmp: Path, scale: float) -> list[str]:
    # 0.05 s cycles at 8 m/s: 0.4 m per column; rows at 0.05 m over a 20 m band
    rows = 400
    cols = int(MAX_CORRIDOR_NODES * scale / rows) - 2
    return [
        *_car_in_clear("corridor"),
        f"--start=-{cols * 0.4 - 6:g}",
        "--goal",
        "6",
        "--lanes=-10:10",
        "--speed",
        "8",
        "--lateral-res",
        "0.05",
        "--out",
        str(tmp / "corridor"),
    ]


def _road(tmp: Path, scale: float) -> list[str]:
    n = int(MAX_GEOMETRIES * scale)
    geoms = "".join(
        f'<geometry s="{i}" x="{i}" y="0" hdg="0" length="1"><line/></geometry>' for i in range(n)
    )
    lanes = (
        '<lanes><laneSection s="0"><center><lane id="0" type="none"/></center><right>'
        '<lane id="-1" type="driving"><width sOffset="0" a="3.5" b="0" c="0" d="0"/>'
        '</lane><lane id="-2" type="driving"><width sOffset="0" a="3.5" b="0" c="0" '
        'd="0"/></lane></right></laneSection></lanes>'
    )
    road = tmp / "long.xodr"
    road.write_text(
        f'<?xml version="1.0"?><OpenDRIVE><header revMajor="1" revMinor="6"/>'
        f'<road id="1" junction="-1" length="{n}"><planView>{geoms}</planView>'
        f"{lanes}</road></OpenDRIVE>"
    )
    return [
        "farfield",
        "--vehicle",
        "system_a",
        "--environment",
        "clear",
        "--road",
        str(road),
        "--ego-lane",
        "-1",
        "--target-lane",
        "-2",
        "--ego-s",
        "10",
        "--length",
        f"{min(300.0, n - 30.0):g}",
        "--out",
        str(tmp / "ff"),
    ]


def _sensors(tmp: Path, scale: float) -> list[str]:
    n = max(1, int(MAX_SENSORS * scale))
    text = (ROOT / "templates" / "vehicles" / "system_a.toml").read_text()
    head, _, mounts = text.partition("[[sensors]]")
    first = "[[sensors]]" + mounts.split("[[sensors]]")[1]
    body = "".join(first.replace('id = "', f'id = "n{i}_', 1) for i in range(n))
    vehicle = tmp / "many_sensors.toml"
    vehicle.write_text(head + body)
    return [
        "nearfield",
        "--vehicle",
        str(vehicle),
        "--resolution",
        "0.05",
        "--out",
        str(tmp / "nf_many"),
    ]


def _search(tmp: Path, scale: float) -> list[str]:
    # every family and environment of System A at the largest budget (measured
    # 2026-11-26: 3 min 44 s, peak 3.07 GiB on the 2-core machine)
    return [
        "search",
        "--vehicle",
        "system_a",
        "--budget",
        str(max(1, int(MAX_BUDGET * scale))),
        "--out",
        str(tmp / "search"),
    ]


CASES = [
    Case("coverage, points", f"{limits.MAX_GRID_CELLS:.0e} cells", _coverage),
    Case("coverage, bodies (--heading)", f"{limits.MAX_BODY_CELLS:.0e} cells", _coverage_bodies),
    Case(
        "coverage, bodies behind occluders",
        f"{limits.MAX_BODY_WORK:.0e} cell-sensor evaluations, {limits.MAX_OCCLUDERS} occluders",
        _coverage_occluded,
    ),
    Case(
        "coverage --per-sensor",
        f"{limits.MAX_PER_SENSOR_CELLS:.0e} map cells",
        _coverage_per_sensor,
    ),
    Case("nearfield", f"resolution {cli.NEARFIELD_RESOLUTION_M[0]:g} m", _nearfield),
    Case("probe", f"{MAX_POINT_SENSOR_VALUES:.0e} point x sensor values", _probe),
    Case("corridor", f"{MAX_CORRIDOR_NODES:.0e} lattice nodes", _corridor),
    Case("farfield on a long road", f"{MAX_GEOMETRIES} geometries", _road),
    Case("nearfield, many sensors", f"{MAX_SENSORS} sensors", _sensors),
    Case("search, every family", f"budget {MAX_BUDGET:.0e}", _search),
]


def run_case(case: Case, scale: float) -> dict[str, float]:
    """Run one case in a fresh child process; its exit code, seconds and peak MiB."""
    with tempfile.TemporaryDirectory(prefix="bench_limits_") as d:
        argv = case.argv(Path(d), scale)
        out = subprocess.run(
            [sys.executable, "-c", CHILD, *argv],
            capture_output=True,
            env={"PYTHONPATH": str(ROOT / "src"), "PATH": "/usr/bin:/bin"},
            timeout=3600,
            check=False,
        )
    lines = out.stdout.decode().strip().splitlines()
    if not lines:
        return {"exit": out.returncode, "seconds": math.nan, "peak_mib": math.nan}
    result: dict[str, float] = json.loads(lines[-1])
    return result


def run(scale: float = 1.0) -> str:
    """Every case at ``scale`` x its limit; returns the Markdown table."""
    rows = []
    for case in CASES:
        r = run_case(case, scale)
        rows.append(
            [
                case.name,
                case.limit,
                f"{scale:g}",
                str(int(r["exit"])),
                f"{r['seconds']:.1f}",
                f"{r['peak_mib']:.0f}",
                "yes" if r["peak_mib"] <= BUDGET_MIB else "no",
            ]
        )
    return (
        "Worst accepted inputs (docs/limits.md), each in a fresh child process\n\n"
        + table(["case", "limit", "scale", "exit", "time [s]", "peak [MiB]", "<= 4 GiB"], rows)
        + "\n"
    )


if __name__ == "__main__":
    print(run(0.1 if "--quick" in sys.argv else 1.0))
