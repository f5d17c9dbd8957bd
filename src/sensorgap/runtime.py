"""Process-wide runtime settings of the command-line tool and the benchmarks.

``tune_allocator``: the search evaluates batches as (B, T) float64 arrays of about 1.6 MB
each, allocated and freed thousands of times per second on two threads. glibc's malloc
serves blocks of that size with ``mmap`` and gives freed memory back to the kernel, so
every batch pays fresh page faults, which serialise the threads in the kernel's memory
map: measured on this project's 2-core machine, two threads evaluated candidates only
1.4x as fast as one. Keeping such blocks on the heap (mmap threshold 32 MiB, trim threshold
1 GiB, top pad 64 MiB; ``mallopt(3)``) brings that to 1.7-1.8x and changes no result. The
price: freed memory stays with the process (its resident size stays near its peak) until
it exits. Not glibc (macOS, musl, Windows): nothing is changed.

``configure_numba_cache``: the compiled kernels are cached on disk (``cache=True``). By
default numba writes the cache beside the source (``__pycache__``) or, when the package
folder is read-only, under the user's home; without a writable package folder and without
``HOME`` every compiling command failed ("no locator available"). On import, sensorgap
points ``NUMBA_CACHE_DIR`` (unless already set) at a writable folder owned by the user:
``$XDG_CACHE_HOME/sensorgap/numba``, ``~/.cache/sensorgap/numba`` or
``<tmp>/sensorgap-numba-<uid>`` (created 0700), and only when the package folder is not
writable. numba checks a cached kernel against its own source file only, not against the
helpers it inlines from other modules (``fastlookup.map_cell`` in ``logmiss._bilinear``):
after an edit or an update of a helper's module alone, the old machine code was reused
silently. ``configure_numba_cache`` therefore keeps a digest of every kernel module's
source beside the cache (``numba-sources.sha256``) and removes the cached kernels when it
no longer matches; a ``NUMBA_CACHE_DIR`` set by the user is left alone.

``guarded_stdout``: a command's standard output that cannot be written (``> /dev/full``, a
pipe whose reader has gone: ``| head -0``) raised ``OSError`` from wherever the command
printed, reported as if one of its files could not be written; a line still buffered
failed only at interpreter exit ("Exception ignored ... OSError", exit code 120). While a
command runs, its ``print`` calls go through a guard that turns such a failure into
``StdoutUnwritable`` and the buffer is flushed before the command returns, so the CLI
reports it as one line (``cli.main``). Over an unbuffered stream (``PYTHONUNBUFFERED``) the
guard writes every byte itself: Python's text layer dropped what a short write left.

``standard_streams``: a process started without its standard streams (``>&-``, ``2>&-``)
has ``sys.stdout`` or ``sys.stderr`` None; printing an error or asking the progress bar's
``isatty()`` was an internal error. The CLI runs inside it: closed descriptors get the null
device, a missing standard error is a stream on it, and a missing standard output is
refused by ``guarded_stdout`` before the command does anything.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import io
import os
import stat
import sys
import tempfile
from collections.abc import Callable, Iterator, MutableMapping
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import Any, TextIO

#: mallopt parameters (glibc <malloc.h>) and the values set, bytes.
_M_TRIM_THRESHOLD, _M_TOP_PAD, _M_MMAP_THRESHOLD = -1, -2, -3
MMAP_THRESHOLD_B = 32 * 1024 * 1024
TRIM_THRESHOLD_B = 1 << 30
TOP_PAD_B = 64 * 1024 * 1024

_done: bool | None = None


def tune_allocator() -> bool:
    """Apply the allocator settings above once per process (glibc only); True if set."""
    global _done
    if _done is not None:
        return _done
    _done = False
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):  # not glibc
        return False
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    mallopt.restype = ctypes.c_int
    _done = bool(
        mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD_B)
        and mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD_B)
        and mallopt(_M_TOP_PAD, TOP_PAD_B)
    )
    return _done


def _private_dir(path: Path) -> bool:
    """Create ``path`` (0700) if needed; True if it is a directory owned by this user that
    no one else may write (a shared temporary folder must not be pre-planted)."""
    try:
        path.mkdir(parents=True, exist_ok=True, mode=0o700)
        st = os.lstat(path)
    except OSError:
        return False
    if not stat.S_ISDIR(st.st_mode) or st.st_mode & (stat.S_IWGRP | stat.S_IWOTH):
        return False
    if hasattr(os, "getuid") and st.st_uid != os.getuid():
        return False
    return os.access(path, os.W_OK | os.X_OK)


def numba_cache_dir(
    package_dir: Path,
    env: MutableMapping[str, str] | None = None,
    writable: Callable[[Path], bool] | None = None,
) -> str | None:
    """Choose numba's cache folder and set ``NUMBA_CACHE_DIR`` in ``env`` (default
    ``os.environ``): None (numba's default beside the source) when ``package_dir`` is
    writable or ``NUMBA_CACHE_DIR`` is already set; else the first usable folder of
    ``$XDG_CACHE_HOME/sensorgap/numba``, ``~/.cache/sensorgap/numba``,
    ``<tmp>/sensorgap-numba-<uid>``, or a fresh temporary folder."""
    env = os.environ if env is None else env
    if env.get("NUMBA_CACHE_DIR"):
        return None
    can_write = writable or (lambda p: os.access(p, os.W_OK | os.X_OK))
    folders = [
        package_dir,
        *(d for d in sorted(package_dir.iterdir()) if d.is_dir() and (d / "__init__.py").is_file()),
    ]
    if all(
        can_write(d / "__pycache__") or (not (d / "__pycache__").exists() and can_write(d))
        for d in folders
    ):
        return None
    candidates = []
    if env.get("XDG_CACHE_HOME"):
        candidates.append(Path(env["XDG_CACHE_HOME"]) / "sensorgap" / "numba")
    if env.get("HOME"):
        candidates.append(Path(env["HOME"]) / ".cache" / "sensorgap" / "numba")
    uid = os.getuid() if hasattr(os, "getuid") else 0
    candidates.append(Path(tempfile.gettempdir()) / f"sensorgap-numba-{uid}")
    chosen = next((str(c) for c in candidates if _private_dir(c)), None)
    if chosen is None:
        chosen = tempfile.mkdtemp(prefix="sensorgap-numba-")
    env["NUMBA_CACHE_DIR"] = chosen
    return chosen


#: The file beside the kernel cache holding the digest of the kernel modules' sources.
SOURCES_STAMP = "numba-sources.sha256"


def kernel_sources_digest(package_dir: Path) -> str:
    """SHA-256 (hex) of the relative paths and contents of the package's modules that
    compile kernels (their text holds ``numba.njit`` or imports ``sensorgap.jit.njit``), in
    path order."""
    import hashlib

    h = hashlib.sha256()
    for path in sorted(package_dir.rglob("*.py")):
        data = path.read_bytes()
        if b"numba.njit" in data or b"from sensorgap.jit import njit" in data:
            h.update(path.relative_to(package_dir).as_posix().encode() + b"\0")
            h.update(data + b"\0")
    return h.hexdigest()


def drop_stale_kernels(package_dir: Path, cache_root: Path) -> bool:
    """Remove numba's cached kernels (``*.nbi``, ``*.nbc``) below ``cache_root`` when the
    digest recorded there (``SOURCES_STAMP``; in ``__pycache__`` when the cache is beside
    the source) is not that of the kernel modules of
    ``package_dir`` now, then record it; True if anything was removed. OS errors are
    ignored (the cache is then only not cleaned)."""
    digest = kernel_sources_digest(package_dir)
    # beside the source: in the package's __pycache__, which version control ignores
    folder = cache_root / "__pycache__" if cache_root == package_dir else cache_root
    stamp = folder / SOURCES_STAMP
    with suppress(OSError):
        if stamp.read_text(encoding="ascii").strip() == digest:
            return False
    removed = False
    for pattern in ("*.nbi", "*.nbc"):
        for old in cache_root.rglob(pattern):
            with suppress(OSError):
                old.unlink()
                removed = True
    with suppress(OSError):
        folder.mkdir(parents=True, exist_ok=True)
        tmp = folder / f".{SOURCES_STAMP}.{os.getpid()}.tmp"
        tmp.write_text(digest + "\n", encoding="ascii")
        os.replace(tmp, stamp)
    return removed


def single_blas_thread() -> None:
    """``OPENBLAS_NUM_THREADS=1`` unless the user set it, for the command line only and
    before numpy is imported (``cli``): sensorgap's linear algebra is 3x3 rotations and
    short vectors, too small for BLAS threads, while OpenBLAS starts one per core at
    import and, when it cannot (a process limit, ``ulimit -u``), printed a line per
    thread from C and stopped the command with SIGINT ("interrupted", exit 130). A
    library user's process is left alone."""
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


def configure_numba_cache() -> str | None:
    """``numba_cache_dir`` for this package, then ``drop_stale_kernels`` in the folder
    used (beside the source, or the one chosen; not a ``NUMBA_CACHE_DIR`` set by the user);
    also updates numba's config when numba was imported first. Never raises: at worst numba
    falls back to its own behaviour."""
    try:
        package_dir = Path(__file__).resolve().parent
        user_set = bool(os.environ.get("NUMBA_CACHE_DIR"))
        chosen = numba_cache_dir(package_dir)
        config = sys.modules.get("numba.core.config")
        if chosen is not None and config is not None:
            config.CACHE_DIR = chosen  # type: ignore[attr-defined]
        if not user_set:
            drop_stale_kernels(package_dir, Path(chosen) if chosen else package_dir)
        return chosen
    except Exception:  # noqa: BLE001 - a cache folder must never stop a command
        return None


def check_numba_environment() -> None:
    """numba reads its ``NUMBA_*`` environment variables when first imported: a value it
    cannot parse was a ``RuntimeWarning`` printed on standard error (``NUMBA_OPT=99``),
    ``NUMBA_NUM_THREADS=0`` an internal error (hostile round twelve). With any such
    variable set (only then: numba is imported here, before the command), either
    raises ``sensorgap.errors.InputError`` naming the variable, its value and why, or
    returns with numba imported."""
    names = sorted(k for k in os.environ if k.startswith("NUMBA_"))
    if not names or "numba" in sys.modules:
        return
    import re
    import warnings

    from sensorgap.errors import InputError

    def refuse(name: str, why: str) -> InputError:
        value = os.environ.get(name, "")
        return InputError(
            f"environment variable {name}", "", f"{value!r}: {why}; unset it or correct it"
        )

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            import numba  # noqa: F401 - reads the NUMBA_* variables
        except Exception as exc:  # noqa: BLE001 - numba's own check of its variables
            name = next(
                (n for n in names if n.removeprefix("NUMBA_").lower() in str(exc).lower()),
                "NUMBA_NUM_THREADS" if "threads" in str(exc).lower() else names[0],
            )
            raise refuse(name, f"numba refuses it ({str(exc).splitlines()[0]})") from None
    for w in caught:
        m = re.search(r"variable '(NUMBA_\w+)' is defined but its associated value", str(w.message))
        if m:
            raise refuse(m.group(1), "numba cannot parse it")


def _usable_dir(path: Path, can_write: Callable[[Path], bool]) -> bool:
    """True if ``path`` is a writable folder, or could be made one: its nearest existing
    ancestor is a writable folder (not a file such as a HOME pointing at one)."""
    probe = path
    try:
        while not probe.exists() and probe != probe.parent:
            probe = probe.parent
        return probe.is_dir() and can_write(probe)
    except OSError:  # an ancestor that may not be searched (HOME another user's 0700 folder)
        return False


def matplotlib_config_dir(
    env: MutableMapping[str, str] | None = None, writable: Callable[[Path], bool] | None = None
) -> str | None:
    """Point ``MPLCONFIGDIR`` (unless set to a usable folder) at a private writable
    folder when matplotlib's default (``$XDG_CONFIG_HOME/matplotlib`` or
    ``~/.config/matplotlib``) cannot be written: otherwise matplotlib prints a
    multi-line warning on every command (held-out review round four: HOME unwritable;
    round six: HOME a file, ``MPLCONFIGDIR`` a file or a read-only folder). An explicit
    ``MPLCONFIGDIR`` that is usable is left alone. Returns the folder chosen, or None."""
    env = os.environ if env is None else env
    can_write = writable or (lambda q: os.access(q, os.W_OK | os.X_OK))
    if env.get("MPLCONFIGDIR"):
        # kept when it is usable (checked on the file system itself); a file or a
        # read-only folder made matplotlib warn on every command (round six)
        if _usable_dir(Path(env["MPLCONFIGDIR"]), lambda q: os.access(q, os.W_OK | os.X_OK)):
            return None
    else:
        base = (
            Path(env["XDG_CONFIG_HOME"])
            if env.get("XDG_CONFIG_HOME")
            else Path(env.get("HOME") or "~").expanduser() / ".config"
        )
        if _usable_dir(base / "matplotlib", can_write):
            return None
    uid = os.getuid() if hasattr(os, "getuid") else 0
    chosen = Path(tempfile.gettempdir()) / f"sensorgap-matplotlib-{uid}"
    folder = (
        str(chosen) if _private_dir(chosen) else tempfile.mkdtemp(prefix="sensorgap-matplotlib-")
    )
    env["MPLCONFIGDIR"] = folder
    return folder


def configure_matplotlib_dir() -> str | None:
    """``matplotlib_config_dir`` for this process, and the Agg backend whatever
    ``MPLBACKEND`` says (``pristine_matplotlib``); never raises."""
    os.environ["MPLBACKEND"] = "agg"
    try:
        return matplotlib_config_dir()
    except Exception:  # noqa: BLE001 - a config folder must never stop a command
        return None


_matplotlib_ready = False


def pristine_matplotlib() -> None:
    """Import matplotlib for sensorgap's figures: the Agg backend and matplotlib's own
    defaults, whatever the user's configuration says. The figures are files (PNG),
    byte-identical for the same inputs, so they must not depend on a ``matplotlibrc`` in
    the working directory, ``MATPLOTLIBRC``, ``MPLCONFIGDIR`` or ``~/.config/matplotlib``,
    nor on ``MPLBACKEND``: hostile round fourteen found ``MPLBACKEND=nosuchbackend`` or
    a Jupyter backend, and an rc file with ``text.usetex: True`` (no LaTeX installed) or
    ``axes.formatter.use_locale``, each an internal error, and an rc ``savefig.dpi``
    changing every figure. The rc files are still read by matplotlib's import (its
    warnings about their bad lines are silenced: the values are dropped right after);
    ``matplotlib.rcdefaults`` then restores the defaults (the style-exempt keys aside:
    backend, timezone, date epoch, which the figures do not use). Call it before
    importing ``matplotlib.pyplot``; idempotent."""
    global _matplotlib_ready
    if _matplotlib_ready:
        return
    import logging

    # MPLBACKEND is already "agg": configure_matplotlib_dir, on import of the package
    log = logging.getLogger("matplotlib")
    level = log.level
    log.setLevel(logging.CRITICAL)
    try:
        import matplotlib
    finally:
        log.setLevel(level)
    matplotlib.rcdefaults()
    matplotlib.use("Agg", force=True)
    matplotlib.rcParams["svg.hashsalt"] = "sensorgap"
    _matplotlib_ready = True


class StdoutUnwritable(Exception):
    """Standard output could not be written (a full device, a closed pipe); ``reason`` is
    the system's message. Not an ``OSError``: a handler of file errors never takes it for
    one of its own files. ``closed``: there was no standard output at all (file descriptor
    1 not open when the process started, ``>&-``), found before the command did anything."""

    def __init__(self, reason: str, closed: bool = False) -> None:
        super().__init__(reason)
        self.reason = reason
        self.closed = closed


def _write_all(raw: Any, data: bytes) -> None:
    """Write every byte of ``data`` to the unbuffered stream ``raw`` (``io.FileIO``): a
    write may take only part of it (a pipe whose reader quits: the kernel returns the
    count written so far), so the rest is written again until done or the stream fails
    (``OSError``, e.g. EPIPE on the next write)."""
    view = memoryview(data)
    while view:
        n = raw.write(view)
        if n is None:  # a non-blocking descriptor that is full: wait until it takes more
            import select

            select.select([], [raw], [])
            continue
        view = view[n:]


class _GuardedStdout:
    """``sys.stdout`` while a command runs: a failed write or flush raises
    ``StdoutUnwritable``; text the stream's encoding cannot take (a path that is not valid
    UTF-8 holds lone surrogates; a UTF-8 locale's stream is strict) is written with
    ``\\udcXX``-style escapes, as standard error does; everything else is the stream's own.
    Over an unbuffered binary layer (``python -u``, ``PYTHONUNBUFFERED``: an ``io.FileIO``)
    the text is encoded and written here until every byte is taken: ``TextIOWrapper``
    writes it with one system call and drops what a short write left (a 6.2 MB ``probe``
    into ``| head -c 100000`` delivered 73,728 bytes and exited 0)."""

    def __init__(self, inner: TextIO) -> None:
        self._inner = inner

    def _encode(self, text: str) -> bytes:
        enc = getattr(self._inner, "encoding", None) or "utf-8"
        if os.linesep != "\n":
            text = text.replace("\n", os.linesep)
        try:
            return text.encode(enc, getattr(self._inner, "errors", None) or "strict")
        except UnicodeEncodeError:
            return text.encode(enc, "backslashreplace")

    def write(self, text: str) -> int:
        try:
            raw = getattr(self._inner, "buffer", None)
            if isinstance(raw, io.RawIOBase):
                self._inner.flush()
                _write_all(raw, self._encode(text))
                return len(text)
            try:
                return self._inner.write(text)
            except UnicodeEncodeError:
                enc = getattr(self._inner, "encoding", None) or "utf-8"
                return self._inner.write(text.encode(enc, "backslashreplace").decode(enc))
        except OSError as exc:
            raise StdoutUnwritable(exc.strerror or type(exc).__name__) from None

    def flush(self) -> None:
        try:
            self._inner.flush()
        except OSError as exc:
            raise StdoutUnwritable(exc.strerror or type(exc).__name__) from None

    def __getattr__(self, name: str) -> Any:
        return getattr(self._inner, name)


def _discard_stdout(stream: TextIO) -> None:
    """After ``stream`` failed: when it is this process's own standard output, point file
    descriptor 1 at the null device, so Python's final flush of what is still buffered
    succeeds instead of printing "Exception ignored" lines (a stream of a caller, e.g. a
    test's capture, is left to its owner)."""
    if stream is not sys.__stdout__:
        return
    with suppress(OSError, ValueError):
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, stream.fileno())
        os.close(null)


@contextmanager
def guarded_stdout() -> Iterator[None]:
    """While the block runs, writing ``sys.stdout`` raises ``StdoutUnwritable`` when the
    stream cannot take it, and the stream is flushed when the block ends (a buffered line
    fails here, not at interpreter exit). After a failure, or when the block raised
    something else and the flush fails too, the process's own standard output is
    discarded (``_discard_stdout``). No standard output at all (``sys.stdout`` is None:
    file descriptor 1 was closed when Python started, ``>&-``) raises
    ``StdoutUnwritable`` (``closed``) before the block runs: the command's printed lines
    would be lost, as into a full device, so it does nothing."""
    inner = sys.stdout
    if inner is None:
        raise StdoutUnwritable("it is closed (file descriptor 1 is not open)", closed=True)
    guard = _GuardedStdout(inner)
    sys.stdout = guard
    try:
        yield
        guard.flush()
    except StdoutUnwritable:
        _discard_stdout(inner)
        raise
    except BaseException:
        try:
            inner.flush()
        except (OSError, ValueError):
            _discard_stdout(inner)
        raise
    finally:
        sys.stdout = inner


def _open_closed_descriptors() -> None:
    """Open the null device on file descriptors 0, 1 and 2 that are not open (a command
    started with ``>&-``, ``2>&-``): otherwise the next file opened takes the number, and
    whatever writes to standard error below Python (a C library, a child process) would
    write into an output file. Inheritable, as the standard descriptors are."""
    for fd in (0, 1, 2):
        try:
            os.fstat(fd)
            continue
        except OSError:
            pass
        with suppress(OSError):
            null = os.open(os.devnull, os.O_RDWR)
            if null != fd:
                os.dup2(null, fd)
                os.close(null)
            os.set_inheritable(fd, True)


class _Discard(io.TextIOBase):
    """A text stream that takes everything and keeps nothing (not a terminal)."""

    def write(self, text: str) -> int:
        return len(text)


class _QuietStderr:
    """``sys.stderr`` while a command runs: a write or flush that fails (a full device, a
    closed pipe or terminal) is dropped, and the rest goes nowhere (the process's own
    descriptor 2 pointed at the null device, so Python's final flush cannot fail either).
    Hostile round twelve: ``2>/dev/full`` turned a bad input's one line (exit 2) into an
    internal error (exit 1). The exit code still says what happened."""

    def __init__(self, inner: TextIO) -> None:
        self._inner = inner
        self._failed = False

    def _drop(self) -> None:
        self._failed = True
        if self._inner is sys.__stderr__:
            with suppress(OSError, ValueError):
                null = os.open(os.devnull, os.O_WRONLY)
                os.dup2(null, self._inner.fileno())
                os.close(null)

    def write(self, text: str) -> int:
        if not self._failed:
            try:
                return self._inner.write(text)
            except (OSError, ValueError):
                self._drop()
        return len(text)

    def flush(self) -> None:
        if not self._failed:
            try:
                self._inner.flush()
            except (OSError, ValueError):
                self._drop()

    def __getattr__(self, name: str) -> Any:
        return getattr(self._inner, name)


@contextmanager
def standard_streams() -> Iterator[None]:
    """The one place that makes a command safe without its standard streams: closed
    descriptors get the null device (``_open_closed_descriptors``) and, while the block
    runs, a missing ``sys.stderr`` (None: descriptor 2 was closed when Python started,
    ``2>&-``) is a stream on the null device, so error lines go nowhere (exit codes stay)
    and progress bars are off (not a terminal); before, ``print(file=sys.stderr)`` wrote
    them to standard output instead and ``sys.stderr.isatty()`` was an internal error.
    Standard error that cannot be written (``_QuietStderr``) loses its lines, not the
    exit code. A missing ``sys.stdout`` is ``guarded_stdout``'s to refuse."""
    _open_closed_descriptors()
    saved = sys.stderr
    opened: TextIO | None = None
    if saved is None:
        try:
            opened = open(  # noqa: SIM115 - closed below
                2, "w", encoding="utf-8", errors="backslashreplace", closefd=False
            )
        except OSError:
            opened = None
    inner = opened or saved
    sys.stderr = _QuietStderr(inner) if inner is not None else _Discard()
    try:
        yield
    finally:
        with suppress(OSError, ValueError):
            sys.stderr.flush()
        sys.stderr = saved
        if opened is not None:
            with suppress(OSError, ValueError):
                opened.close()


class DeferredStop:
    """Stop signals (Ctrl-C, SIGTERM, SIGHUP) held back from ``begin()`` to the end of the
    ``with`` block, then delivered: the last writes of a command that must happen together
    (a search's ranking files, the exact results its store records for them and the
    folder's manifest) all happen, or, stopped before ``begin()``, none of them.

    Hostile round eighteen (F7): Ctrl-C during ``search --resume`` after it rewrote
    ``ranking.json`` and the other ranking files but before its ``manifest.json`` left a
    folder that failed its own ``verify``. A signal received in the block is recorded and
    sent again, to the handler in place before ``begin()``, when the block ends (the
    command then stops as interrupted, its folder complete). The window is the writing of
    a few files (about a second for a large store's manifest). Only in the main thread
    (where Python runs signal handlers); elsewhere ``begin()`` does nothing."""

    _SIGNALS = ("SIGINT", "SIGTERM", "SIGHUP")

    def __init__(self) -> None:
        self._previous: dict[int, Any] = {}
        self._pending: list[int] = []

    def __enter__(self) -> DeferredStop:
        return self

    def begin(self) -> None:
        """Hold stop signals from now until the block ends (idempotent)."""
        import signal
        import threading

        if self._previous or threading.current_thread() is not threading.main_thread():
            return
        for name in self._SIGNALS:
            sig = getattr(signal, name, None)
            if sig is not None:
                self._previous[int(sig)] = signal.signal(sig, self._hold)

    def _hold(self, signum: int, frame: Any) -> None:
        self._pending.append(int(signum))

    def __exit__(self, *exc: object) -> None:
        import signal

        for sig, handler in self._previous.items():  # None: not set from Python
            signal.signal(sig, signal.SIG_DFL if handler is None else handler)
        self._previous.clear()
        if self._pending:  # delivered now, to the handlers put back above
            os.kill(os.getpid(), self._pending[0])
            self._pending.clear()


def _stop_signals() -> set[int]:
    """Ctrl-C, SIGTERM and SIGHUP, those this platform has."""
    import signal

    return {int(getattr(signal, n)) for n in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, n)}


@contextmanager
def children_spared_stop_signals() -> Iterator[None]:
    """Stop signals (Ctrl-C, SIGTERM, SIGHUP) blocked in this thread for the block: the
    processes and threads started in it inherit them blocked, so a signal to the whole
    process group (a terminal's Ctrl-C, a closed terminal's SIGHUP, ``timeout``) does not
    reach them; this process, stopping, ends them itself (hostile round twenty, F3: a
    local Dask cluster's workers and its multiprocessing resource tracker died of the
    group's signal and printed warnings and tracebacks). A signal to this process during
    the block is delivered after it. A child that must react to signals unblocks them
    itself (``search.daskworker``)."""
    import signal

    if not hasattr(signal, "pthread_sigmask"):
        yield
        return
    old = signal.pthread_sigmask(signal.SIG_BLOCK, _stop_signals())
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def start_resource_tracker() -> None:
    """Start multiprocessing's resource tracker (a process every spawned child needs)
    with the stop signals blocked, which it inherits (``children_spared_stop_signals``):
    a closed terminal (SIGHUP to the whole process group) killed it, and multiprocessing
    printed a warning and tracebacks on standard error while relaunching it (hostile
    round nineteen, F7). It ends when this process does."""
    from multiprocessing import resource_tracker

    with children_spared_stop_signals():
        resource_tracker.ensure_running()
