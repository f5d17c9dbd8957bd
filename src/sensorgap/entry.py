"""The ``sensorgap`` console script and ``python -m sensorgap``: stop signals are handled
from the start (``earlystop``), before the command line's modules are imported."""

from __future__ import annotations

import signal
import sys

from sensorgap.earlystop import install as install_early_stop


def main() -> int:
    """Run the command of ``sys.argv`` (``cli.main``); its exit code."""
    install_early_stop(always=True)
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
