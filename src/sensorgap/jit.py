"""``njit``: numba's ``njit`` with its on-disk cache (``cache=True``) when the cache can be
used, else compiled in memory for the process (slower start, same machine code).

numba looks for a writable cache folder when a kernel is decorated (at import) and raised
``RuntimeError: cannot cache function ...: no locator available`` when it found none: every
compiling command then failed as an internal error. That happened with a umask that takes
the owner's write permission (``umask 277``: the folders numba made for its cache were
read-only to their owner, so the next command, any umask, failed too) and with a cache
folder left read-only by such a run. Now:

* a umask that takes the owner's read or write permission (``umask & 0o600``) turns the
  cache off for the process (numba's files would be unreadable or its folders unwritable
  to their owner);
* a kernel whose cache numba cannot place is compiled without it.

``runtime.configure_numba_cache`` chooses the folder (docs/limits.md).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any, TypeVar

import numba

F = TypeVar("F", bound=Callable[..., Any])

#: The text numba raises when no cache folder can be used for a kernel's source file.
NO_LOCATOR = "no locator available"


def current_umask() -> int:
    """The process's umask (Linux: read from ``/proc/self/status``, thread-safe; else set
    and restored)."""
    try:
        with open("/proc/self/status", encoding="ascii") as f:
            for line in f:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def cache_usable() -> bool:
    """Whether numba's on-disk cache can work under this process's umask: its owner keeps
    read and write permission on the files and folders numba makes."""
    return not current_umask() & 0o600


def njit(**options: Any) -> Callable[[F], F]:
    """``numba.njit(cache=True, **options)``, or without the cache when it cannot be used
    (``cache_usable``, or numba finds no folder for it: ``NO_LOCATOR``)."""

    def wrap(func: F) -> F:
        if cache_usable():
            try:
                return numba.njit(cache=True, **options)(func)
            except RuntimeError as exc:
                if NO_LOCATOR not in str(exc):
                    raise
        return numba.njit(**options)(func)

    return wrap
