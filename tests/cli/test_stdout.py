"""A standard output that cannot be written (``> /dev/full``, a pipe whose reader has gone)
is one line and exit 2 in a real process, buffered or not (no "Exception ignored" lines at
interpreter exit, no exit code 120); a new --out is removed, an existing one kept."""

from __future__ import annotations

import os
import subprocess
import sys
from contextlib import redirect_stdout, suppress
from pathlib import Path

import pytest

import sensorgap
from sensorgap.cli import main

SRC = str(Path(sensorgap.__file__).resolve().parents[1])


def _child(argv: list[str], stdout: int, unbuffered: bool) -> tuple[int, list[str]]:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}
    env["PYTHONPATH"] = SRC
    if unbuffered:
        env["PYTHONUNBUFFERED"] = "1"
    proc = subprocess.run(
        [sys.executable, "-m", "sensorgap", *argv],
        stdout=stdout,
        stderr=subprocess.PIPE,
        env=env,
        timeout=120,
        check=False,
    )
    return proc.returncode, proc.stderr.decode().strip().splitlines()


@pytest.mark.parametrize("unbuffered", [False, True], ids=["buffered", "unbuffered"])
def test_nearfield_into_a_full_device(tmp_path: Path, unbuffered: bool) -> None:
    out = tmp_path / "nf"
    with open("/dev/full", "wb") as full:
        code, err = _child(
            ["nearfield", "--vehicle", "system_a", "--resolution", "1", "--out", str(out)],
            full.fileno(),
            unbuffered,
        )
    assert code == 2 and len(err) == 1, err
    assert err[0].startswith(
        "sensorgap: error: stdout: cannot write: No space left on device"
    ) and err[0].endswith(f"removed {out}, which it had written")
    assert not out.exists()


def test_schema_into_a_closed_pipe() -> None:
    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        code, err = _child(["schema", "vehicle"], write_end, unbuffered=False)
    finally:
        os.close(write_end)
    assert code == 2 and len(err) == 1, err
    assert err[0] == (
        "sensorgap: error: stdout: cannot write: Broken pipe (a full device or a closed "
        "pipe); the command stopped"
    )


def test_an_existing_out_folder_is_kept(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Into a folder that existed (it may be a certified run folder), what the command
    wrote stays: complete and listed in its manifest; only the printed line is lost."""
    out = tmp_path / "nf"
    out.mkdir()
    full = open("/dev/full", "w", encoding="utf-8")  # noqa: SIM115 - closed below
    with redirect_stdout(full):
        code = main(["nearfield", "--vehicle", "system_a", "--resolution", "1", "--out", str(out)])
    with suppress(OSError):  # its buffered line cannot be flushed either
        full.close()
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and err[0].endswith("; the command stopped"), err
    assert main(["verify", str(out)]) == 0
