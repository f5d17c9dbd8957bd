"""Running ``sensorgap.cli.main`` in a forked child process: for a test that needs a
process of its own (a file size limit, which would hold for the tests too) but not a
fresh interpreter. The child is a copy of the test process with sensorgap imported and
its kernels loaded; a fresh interpreter spent 1.5-2 s per case starting, importing and
loading them."""

from __future__ import annotations

import os
import sys
import warnings
from collections.abc import Callable, Mapping, Sequence
from contextlib import suppress
from typing import TextIO

#: Exit code of a child whose ``main`` raised (the test then fails on it), as sysexits'
#: EX_SOFTWARE.
CHILD_CRASHED = 70


def run_forked(
    argv: Sequence[str],
    before: Callable[[], None] | None = None,
    env: Mapping[str, str] | None = None,
    stdout: TextIO | None = None,
) -> tuple[int, str]:
    """(exit code, standard error) of ``main(argv)`` in a forked child: ``before`` runs in
    the child first (e.g. ``resource.setrlimit``), ``env`` is added to its environment,
    its standard output goes to ``stdout`` (None: /dev/null), its standard error to a
    pipe read here. Python ignores SIGXFSZ, so a write beyond a file size limit fails with
    EFBIG as in a fresh process. The child leaves by ``os._exit``, running none of this
    process's exit handlers."""
    from sensorgap.cli import main

    read_end, write_end = os.pipe()
    with warnings.catch_warnings():
        # Python 3.12+ warns that forking a process with threads (the suite's numba and
        # pytest-xdist threads) may deadlock the child on a lock one of them held; the
        # child only runs sensorgap's main and leaves by os._exit: a deadlock would hang the
        # test visibly, never pass it wrongly (none seen; 3.11 forked the same, silently)
        warnings.simplefilter("ignore", DeprecationWarning)
        pid = os.fork()
    if pid == 0:  # the child: never returns
        code = CHILD_CRASHED
        try:
            os.close(read_end)
            os.dup2(write_end, 2)
            out = os.open(os.devnull, os.O_WRONLY) if stdout is None else stdout.fileno()
            os.dup2(out, 1)
            sys.stdout = open(1, "w", encoding="utf-8", closefd=False)  # noqa: SIM115
            sys.stderr = open(2, "w", encoding="utf-8", closefd=False)  # noqa: SIM115
            os.environ.update(env or {})
            if before is not None:
                before()
            try:
                code = main(list(argv))
            except SystemExit as exc:
                code = int(exc.code or 0)
            for stream in (sys.stdout, sys.stderr):
                with suppress(OSError, ValueError):
                    stream.flush()
        finally:
            os._exit(code)
    os.close(write_end)
    chunks = []
    with open(read_end, "rb") as pipe:
        while chunk := pipe.read(65536):
            chunks.append(chunk)
    _, status = os.waitpid(pid, 0)
    return os.waitstatus_to_exitcode(status), b"".join(chunks).decode("utf-8", "replace")
