"""Same inputs and seed -> byte-identical XML, CSV, JSON (and PNG, NPZ, HTML, Markdown) from
every command; the report's generation time is its one timestamp (fixed here with
SOURCE_DATE_EPOCH). SQLite stores are compared by content, not bytes."""

from __future__ import annotations

import contextlib
import sqlite3
from pathlib import Path

import pytest

from sensorgap.analysis.nearfield import clear_memo
from sensorgap.cli import main

COMMANDS = {
    "coverage": [
        "coverage",
        "--vehicle",
        "system_b",
        "--environment",
        "glare_front_right",
        "--target",
        "car",
        "--resolution",
        "0.5",
        "--extent",
        "-20,120,-20,20",
        "--per-sensor",
        "--out",
        "{out}",
    ],
    "nearfield": ["nearfield", "--vehicle", "system_a", "--resolution", "0.1", "--out", "{out}"],
    "farfield": [
        "farfield",
        "--vehicle",
        "system_b",
        "--environment",
        "rain_25",
        "--road",
        "motorway_r500",
        "--ego-lane",
        "-1",
        "--ego-s",
        "450",
        "--target-lane",
        "-2",
        "--out",
        "{out}",
    ],
    "corridor": [
        "corridor",
        "--vehicle",
        "system_b",
        "--environment",
        "rain_25",
        "--target",
        "car",
        "--out",
        "{out}",
    ],
    "search+export+report": [
        "search",
        "--vehicle",
        "system_b",
        "--families",
        "slow_ahead_curve,crossing_cyclist",
        "--environments",
        "clear,glare_front_right,snow",
        "--budget",
        "600",
        "--seed",
        "4",
        "--top",
        "4",
        "--out",
        "{out}",
    ],
}


def _run(name: str, out: Path) -> None:
    argv = [a.replace("{out}", str(out)) for a in COMMANDS[name]]
    assert main(argv) == 0
    if name.startswith("search"):
        assert main(["export", "--run", str(out), "--osc-version", "1.3"]) == 0
        assert main(["report", "--run", str(out)]) == 0


def _table(db: Path) -> list[tuple[object, ...]]:
    with contextlib.closing(sqlite3.connect(db)) as c:  # (a with alone leaves it open)
        return c.execute("SELECT * FROM candidates ORDER BY family, idx").fetchall()


@pytest.mark.slow
@pytest.mark.parametrize("name", list(COMMANDS))
def test_byte_identical_outputs(name: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1767225600")
    out, a, b = tmp_path / "out", tmp_path / "a", tmp_path / "b"
    _run(name, out)  # same inputs, same output folder, twice
    out.rename(a)
    clear_memo()  # computed again, not copied from the first run's near field
    _run(name, out)
    out.rename(b)
    files_a = sorted(p.relative_to(a) for p in a.rglob("*") if p.is_file())
    files_b = sorted(p.relative_to(b) for p in b.rglob("*") if p.is_file())
    assert files_a == files_b
    kinds = {p.suffix for p in files_a}
    assert kinds & {".csv", ".json"}
    differ = [
        str(p)
        for p in files_a
        if p.suffix != ".sqlite" and (a / p).read_bytes() != (b / p).read_bytes()
    ]
    assert differ == [], f"not byte-identical: {differ}"
    for p in files_a:
        if p.suffix == ".sqlite":
            assert _table(a / p) == _table(b / p)
    if name.startswith("search"):
        assert {".xosc", ".xodr", ".html", ".md", ".png"} <= kinds
