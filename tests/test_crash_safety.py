"""Crash safety: a search killed with SIGKILL resumes with --resume and ends with the same
ranking as an uninterrupted run; outputs are atomic and every run folder has a manifest."""

from __future__ import annotations

import json
import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest

import sensorgap
from sensorgap.cli import main

SRC = str(Path(sensorgap.__file__).resolve().parents[1])
ARGS = [
    "search",
    "--vehicle",
    "system_b",
    "--families",
    "cut_in_left,crossing_pedestrian",
    "--environments",
    "clear,fog_50",
    "--budget",
    "12000",
    "--seed",
    "5",
    "--top",
    "8",
    "--strategy",
    "random",
    "--workers",
    "1",
]


def _cli(args: list[str]) -> subprocess.Popen[bytes]:
    env = {**os.environ, "PYTHONPATH": SRC}
    return subprocess.Popen(
        [sys.executable, "-m", "sensorgap", *args],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )


def _rows(db: Path) -> int:
    try:
        with sqlite3.connect(db) as c:
            return int(c.execute("SELECT COUNT(*) FROM candidates").fetchone()[0])
    except sqlite3.Error:
        return 0


@pytest.mark.slow
def test_sigkill_then_resume_gives_the_uninterrupted_ranking(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    full, killed = tmp_path / "full", tmp_path / "killed"
    ref = _cli([*ARGS, "--out", str(full)])
    proc = _cli([*ARGS, "--out", str(killed)])
    db = killed / "search.sqlite"
    deadline = time.monotonic() + 120
    while _rows(db) == 0 and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.02)
    assert proc.poll() is None, "the search ended before it could be killed"
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert proc.returncode == -signal.SIGKILL
    n_before = _rows(db)
    assert 0 < n_before < 12000
    assert not (killed / "ranking.csv").exists()
    assert not list(killed.glob(".*.tmp*"))  # no half-written file left behind
    # without --resume the folder is refused (in this process: a refusal needs no
    # process of its own), with it the search continues
    assert main([*ARGS, "--out", str(killed)]) == 2
    err = capsys.readouterr().err
    assert "--resume" in err and err.count("\n") == 1
    resumed = _cli([*ARGS, "--out", str(killed), "--resume"])
    out, err = resumed.communicate(timeout=300)
    assert resumed.returncode == 0, err.decode()
    assert f"{n_before} reused".encode() in out
    ref.communicate(timeout=300)
    assert ref.returncode == 0
    assert (killed / "ranking.csv").read_bytes() == (full / "ranking.csv").read_bytes()
    assert (killed / "ranking.json").read_bytes() == (full / "ranking.json").read_bytes()
    manifest = json.loads((killed / "manifest.json").read_text())
    assert {"ranking.csv", "ranking.json", "search.sqlite", "summary.json"} <= set(
        manifest["files"]
    )
