"""Run folders shared by the report tests (made once per session): a small default job
(coverage, near field, far field, search, export, report of System A), a search-only run of
System B, and the A-vs-B report of two search runs."""

from __future__ import annotations

from pathlib import Path

import pytest

from sensorgap.cli import main
from sensorgap.jobs import run_default
from sensorgap.search.run import run_search


@pytest.fixture(scope="session")
def job(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """System A's default job, small: 2,100 candidates (3 searches of 700), the top 5
    ranked and exported (the fourth has an occluder, a lead car cutting out); in one
    process (the second one costs 3 s of CPU; tests/cli/test_run_vehicle.py runs the job
    with it)."""
    out = tmp_path_factory.mktemp("job")
    run_default(out, budget=2100, top=5, workers=1)
    return out / "system_a"


@pytest.fixture(scope="session")
def search_only(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A search run of System B with nothing else (no near field, coverage, far field,
    export), its report written."""
    out = tmp_path_factory.mktemp("search_only")
    run_search(
        "system_b", ["slow_ahead_curve"], ["snow"], 60, 1, 2, out, strategy="lhs", progress=False
    )
    assert main(["report", "--run", str(out)]) == 0
    return out


@pytest.fixture(scope="session")
def compared(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``report --compare`` of two search runs over two families in clear weather and 50 m
    fog: System A with nothing else, System B with its near field. The comparison computes
    what each lacks (A's near field, both vehicles' coverage maps and far field) and the
    difference maps. (It compared the default job's seven environments before: 17 s of
    CPU, most of it drawing seven coverage, far-field and difference figures more.)"""
    from sensorgap.analysis.nearfield import write_nearfield
    from sensorgap.models import load_system

    base = tmp_path_factory.mktemp("compare")
    for name in ("system_a", "system_b"):
        run_search(
            name,
            ["crossing_pedestrian", "stopped_rural_curve"],
            ["clear", "fog_50"],
            300,
            1,
            4,
            base / name,
            strategy="lhs",
            progress=False,
        )
    write_nearfield(load_system("system_b"), base / "system_b" / "nearfield")
    out = base / "cmp"
    assert (
        main(
            [
                "report",
                "--compare",
                str(base / "system_a"),
                str(base / "system_b"),
                "--out",
                str(out),
            ]
        )
        == 0
    )
    return out
