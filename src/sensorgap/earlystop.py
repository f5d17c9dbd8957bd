"""Stop signals of the ``sensorgap`` command before its command line is imported.

Importing the package and ``sensorgap.cli`` (pydantic, numpy, the command table) takes
0.2-1 s, longer under load. A Ctrl-C in that window printed a KeyboardInterrupt traceback,
and a SIGTERM or SIGHUP ended the process with exit 143 or 129 and no line (hostile rounds
seventeen to nineteen). Nothing is written before ``cli.main`` runs, so a stop signal
there only needs its line and its exit code: ``install`` sets that up, first thing in the
package's ``__init__`` when the process is the command, and again in ``entry.main``; from
the moment ``cli.main`` installs its own handlers, those stop the command (and put back
what it wrote). Only the interpreter's own start, before any of sensorgap's code runs
(about 20 ms), is not covered. Imports only modules built into the interpreter."""

import os
import signal
import sys

#: The stop signals of ``cli`` (Ctrl-C, SIGTERM, SIGHUP) that exist on this platform.
SIGNALS = tuple(
    getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name)
)


def stop_before_work(signum: int, frame: object) -> None:
    """A stop signal before the command started: its line, exit 128 + signal number."""
    try:  # noqa: SIM105 - contextlib is not imported this early
        os.write(2, b"sensorgap: interrupted\n")
    except OSError:  # no standard error (``2>&-``): the exit code still says it
        pass
    os._exit(128 + signum)


def module_run(argv: list[str]) -> str | None:
    """The module an interpreter command line ``argv`` (``sys.orig_argv``) runs with
    ``-m``, after any interpreter options (``python -u -I -X dev -m sensorgap``, ``-um``,
    ``-msensorgap``), or None (a script, ``-c``, standard input)."""
    i = 1
    while i < len(argv):
        arg = argv[i]
        if arg == "-" or not arg.startswith("-"):
            return None  # a script file or standard input
        if arg.startswith("--"):  # --check-hash-based-pycs takes a value; the rest none
            i += 2 if arg == "--check-hash-based-pycs" else 1
            continue
        for k, letter in enumerate(arg[1:], start=1):
            rest = arg[k + 1 :]
            if letter == "c":
                return None
            if letter == "m":
                return rest or (argv[i + 1] if i + 1 < len(argv) else None)
            if letter in "WX":  # their value: the rest of the cluster or the next argument
                i += 0 if rest else 1
                break
        i += 1
    return None


def is_the_command_line() -> bool:
    """Whether this process is the ``sensorgap`` command: the console script (the main
    module's file is named ``sensorgap``) or ``python [options] -m sensorgap`` (hostile
    round twenty: with an interpreter option before ``-m`` it was not recognised). A
    program that imports the package as a library keeps its own signal handlers."""
    script = getattr(sys.modules.get("__main__"), "__file__", None) or ""
    orig = list(getattr(sys, "orig_argv", []))
    return os.path.basename(str(script)) == "sensorgap" or module_run(orig) in (
        "sensorgap",
        "sensorgap.__main__",
    )


def install(always: bool = False) -> None:
    """``stop_before_work`` for every stop signal, in the ``sensorgap`` command only
    (``is_the_command_line``; ``always``: whatever the process), from its main thread
    (elsewhere nothing: ``signal.signal`` works there only)."""
    if not (always or is_the_command_line()):
        return
    try:
        for sig in SIGNALS:
            signal.signal(sig, stop_before_work)
    except ValueError:  # not the main thread
        pass
