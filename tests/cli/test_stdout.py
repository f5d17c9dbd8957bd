"""A standard output that cannot be written (``> /dev/full``, a pipe whose reader has gone)
is one line and exit 2 in a real process, buffered or not (no "Exception ignored" lines at
interpreter exit, no exit code 120); a new --out is removed, an existing one kept."""

from __future__ import annotations

import io
import os
import subprocess
import sys
from collections.abc import Callable
from contextlib import redirect_stdout, suppress
from pathlib import Path
from typing import Any

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


class _ShortWrites(io.RawIOBase):
    """An unbuffered binary stream taking at most ``step`` bytes a write, as a pipe does
    for a write its reader has not made room for (``write(2)`` returns the count)."""

    def __init__(self, step: int) -> None:
        self.data = bytearray()
        self.step = step

    def writable(self) -> bool:
        return True

    def write(self, b: Any) -> int:
        taken = bytes(b[: self.step])
        self.data += taken
        return len(taken)


def test_short_writes_of_an_unbuffered_stdout_are_written_again(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """Hostile round ten: with ``PYTHONUNBUFFERED`` standard output is a ``TextIOWrapper``
    over an ``io.FileIO``, which writes a string with one system call and drops whatever a
    short write left: a 6.2 MB ``probe`` into ``| head -c 100000`` delivered 73,728 bytes
    and exited 0. Every byte must arrive (or the command fail)."""
    assert main(["schema", "vehicle"]) == 0
    expected = capsys.readouterr().out.encode("utf-8")
    assert len(expected) > 5000
    raw = _ShortWrites(1000)
    with redirect_stdout(io.TextIOWrapper(raw, encoding="utf-8", write_through=True)):
        assert main(["schema", "vehicle"]) == 0
    assert bytes(raw.data) == expected


def test_probe_into_a_pipe_whose_reader_quits_early(tmp_path: Path) -> None:
    """The reported case in a real process, unbuffered: the reader takes 100,000 bytes of
    a 0.6 MB probe and quits; the command says so (exit 2), it no longer exits 0."""
    points = tmp_path / "p.csv"
    points.write_text("x,y\n" + "".join(f"{i % 40},{i // 40 - 25}\n" for i in range(2000)))
    env = {**os.environ, "PYTHONPATH": SRC, "PYTHONUNBUFFERED": "1"}
    argv = ["probe", "--vehicle", "system_b", "--environment", "clear", "--target", "car"]
    proc = subprocess.Popen(
        [sys.executable, "-m", "sensorgap", *argv, "--points", str(points)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=env,
    )
    assert proc.stdout is not None and proc.stderr is not None
    got = proc.stdout.read(100_000)
    proc.stdout.close()
    err = proc.stderr.read().decode().strip().splitlines()
    proc.stderr.close()
    assert proc.wait(timeout=120) == 2, err
    assert len(got) == 100_000
    assert err == [
        "sensorgap: error: stdout: cannot write: Broken pipe (a full device or a closed "
        "pipe); the command stopped"
    ]


def _closing(*fds: int) -> Callable[[], None]:
    def close() -> None:
        for fd in fds:
            os.close(fd)

    return close


def test_closed_standard_streams_in_a_real_process(tmp_path: Path) -> None:
    """Hostile round ten: a process started without standard error (``2>&-``) had
    ``sys.stderr`` None: the search's progress bar (``sys.stderr.isatty()``) was an
    internal error that left a partial run folder, and error lines went to standard
    output. Now the search runs (no progress bar, its folder verified); without both
    streams an error is still exit 2 (its line cannot be shown) and nothing is written."""
    env = {**os.environ, "PYTHONPATH": SRC}
    out = tmp_path / "s"
    search = ["search", "--vehicle", "system_b", "--families", "slow_ahead_curve"]
    search += ["--environments", "clear", "--budget", "40", "--out", str(out)]
    done = subprocess.run(
        [sys.executable, "-m", "sensorgap", *search],
        stdout=subprocess.PIPE,
        env=env,
        preexec_fn=_closing(2),
        timeout=300,
        check=False,
    )
    assert done.returncode == 0, done.stdout
    assert f"{out}: 40 evaluated" in done.stdout.decode()
    assert main(["verify", str(out)]) == 0
    bad = ["nearfield", "--vehicle", str(tmp_path / "nope.toml"), "--out", str(tmp_path / "x")]
    for closed in ((2,), (1, 2)):
        done = subprocess.run(
            [sys.executable, "-m", "sensorgap", *bad],
            stdout=subprocess.PIPE,
            env=env,
            preexec_fn=_closing(*closed),
            timeout=120,
            check=False,
        )
        assert done.returncode == 2 and done.stdout == b"", (closed, done.stdout)
        assert not (tmp_path / "x").exists()
