"""The ``sensorgap`` console script and ``python -m sensorgap``: stop signals are handled
from the first line, before the command line's modules are imported.

Importing ``sensorgap.cli`` (pydantic, numpy, the command table) takes 0.2-1 s, longer
under load. A Ctrl-C in that window printed a 20-line ``KeyboardInterrupt`` traceback, and a
SIGTERM or SIGHUP ended the process with exit 143 or 129 and no line (hostile round
eighteen, F8; the exit 143 without a line of round seventeen). Nothing is written before
``cli.main`` runs, so a stop signal there only needs its line and its exit code; from the
moment ``cli.main`` installs its own handlers, those stop the command (and put back what it
wrote)."""

from __future__ import annotations

import contextlib
import os
import signal
import sys
from typing import Any

#: The stop signals of ``cli`` (Ctrl-C, SIGTERM, SIGHUP) that exist on this platform.
_EARLY_SIGNALS = tuple(
    getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name)
)


def _stop_before_work(signum: int, frame: Any) -> None:
    """A stop signal before the command started: its line, exit 128 + signal number."""
    with contextlib.suppress(OSError):  # no standard error (``2>&-``): the code says it
        os.write(2, b"sensorgap: interrupted\n")
    os._exit(128 + signum)


def main() -> int:
    """Run the command of ``sys.argv`` (``cli.main``); its exit code."""
    for sig in _EARLY_SIGNALS:
        signal.signal(sig, _stop_before_work)
    from sensorgap.cli import main as cli_main

    # Ctrl-C is a KeyboardInterrupt again for ``cli.main``, which stops the command by it
    # (SIGTERM and SIGHUP: it installs its own handlers before any work)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        return cli_main()
    except KeyboardInterrupt:  # before ``cli.main`` took over: nothing written yet
        print("sensorgap: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
