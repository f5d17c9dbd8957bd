"""Fill numba's on-disk cache (``cache=True`` kernels) before parallel test workers start.

From a fresh clone no kernel is cached yet: every pytest-xdist worker would compile the
same ~30 kernels itself, and under coverage tracing numba's (pure Python) compiler runs
several times slower. ``tests/conftest.py`` runs this file once, in its own process (no
coverage tracing), when ``pytest -n N`` starts; the workers then load the compiled kernels.
``make test`` runs it earlier (``--if-cold``), beside mypy: both use one core each.
It runs small real commands (a search in lookup and in exact mode over every family, a
coverage map); it checks nothing, the suite does. When the cache is already warm
(``cache_is_warm``) nothing runs."""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import importlib
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

#: Kernels whose cache index files tell whether the cache was filled (module:name).
KERNELS = (
    "sensorgap.search.outcome:_first_confirmation_kernel",
    "sensorgap.search.fastmetrics:summarize",
    "sensorgap.coverage.fastlookup:lookup_pass",
    "sensorgap.coverage.fastkernel:accumulate_log_miss",
    "sensorgap.scenarios.fastpath:path_states",
)


def lock_path() -> Path:
    """The lock a running warm-up holds (one per checkout, in the temporary folder): test
    workers wait on it before their first test (``wait_for_warmup``), so ``make test`` can
    start pytest, whose workers start and collect meanwhile, while the warm-up ends."""
    tag = hashlib.sha256(str(Path(__file__).resolve().parent).encode()).hexdigest()[:16]
    return Path(tempfile.gettempdir()) / f"sensorgap-numba-warmup-{tag}.lock"


@contextlib.contextmanager
def _locked(mode: int) -> Iterator[bool]:
    """``flock`` of ``lock_path`` in ``mode``; yields False when ``LOCK_NB`` is in ``mode``
    and the lock is held elsewhere (released with the file, also when a process dies)."""
    with open(lock_path(), "a+b") as f:
        try:
            fcntl.flock(f, mode)
        except BlockingIOError:
            yield False
            return
        try:
            yield True
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


def warmup_running() -> bool:
    """Whether a warm-up holds its lock now."""
    with _locked(fcntl.LOCK_EX | fcntl.LOCK_NB) as free:
        return not free


def wait_for_warmup() -> None:
    """Block until no warm-up holds its lock (at once when none runs)."""
    with _locked(fcntl.LOCK_SH):
        pass


def cache_is_warm() -> bool:
    """True when numba's cache holds an index file for every kernel of ``KERNELS`` (in the
    cache folder this process would use). Uses numba internals; any surprise -> False."""
    try:
        for spec in KERNELS:
            module, name = spec.split(":")
            dispatcher = getattr(importlib.import_module(module), name)
            index = Path(dispatcher._cache._cache_file._index_path)
            if not index.is_file():
                return False
        return True
    except Exception:  # noqa: BLE001 - a numba change: just warm the cache
        return False


def warm(out: Path) -> None:
    """Run the commands whose kernels the suite uses most, into ``out``."""
    from sensorgap.cli import main

    envs = "clear,glare_front_right,fog_50"
    for pd in ("lookup", "exact"):
        main(
            [
                "search",
                "--vehicle",
                "system_b",
                "--families",
                "all",
                "--environments",
                envs,
                "--budget",
                "120",
                "--top",
                "2",
                "--strategy",
                "lhs",
                "--pd",
                pd,
                "--out",
                str(out / f"search_{pd}"),
            ]
        )
    main(
        [
            "coverage",
            "--vehicle",
            "system_a",
            "--environment",
            "glare_front_right",
            "--target",
            "car",
            "--resolution",
            "2",
            "--extent",
            "-20,60,-20,20",
            "--out",
            str(out / "coverage"),
        ]
    )


if __name__ == "__main__":
    # the lock first, before the slow imports: pytest, started meanwhile, must see it held
    with _locked(fcntl.LOCK_EX):
        # --if-cold: nothing when the cache is already warm (``make test`` runs this beside
        # mypy, and pytest starts without waiting for it)
        if "--if-cold" in sys.argv[1:] and cache_is_warm():
            sys.exit(0)
        with tempfile.TemporaryDirectory(prefix="sensorgap-warmup-") as tmp:
            warm(Path(tmp))
    sys.exit(0)
