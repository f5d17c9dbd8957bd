"""Who is writing which folder: the lock of a folder a command writes, and the marker
of a folder it is writing now.

- ``folder_lock``: an exclusive ``flock`` on the folder itself, taken before any work by
  every command that writes a run folder; a second command into the same folder is
  refused at once.
- ``writing``: taken once a command has passed its own refusals and is about to write: a
  shared open-file-description lock (Linux ``F_OFD_SETLK``, independent of the ``flock``)
  on one byte of the folder, byte ``WRITES`` for a command writing some files there
  (``evaluate``, ``probe``), byte ``CERTIFIES`` for one whose manifest will list all that
  lies below it (a search run, a map, a catalog, a report). A command is refused when a
  folder above its own is being certified by another command, and a certifying one also
  when a folder below its own is being written (hostile round 37: ``nearfield --out
  P/sub`` while ``corridor --out P`` ran, or the other way round; both ended with exit
  0 and ``verify P`` failed). The ``flock`` alone could not tell: a command also holds it
  for a moment while it refuses (``coverage --out /``), and other programs take it.

Both are dropped by the system when the process ends, killed or not: no lock file.
"""

from __future__ import annotations

import fcntl
import os
import struct
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

from sensorgap.errors import InputError

#: The folder locks this process holds (``folder_lock``): (device, inode) of the folder
#: -> [open descriptor holding the ``flock``, how many blocks hold it now, the thread
#: that holds it]. A lock or marker another thread of this process holds counts as
#: another command's (hostile round 40: two ``find_scenarios`` calls on threads of one
#: process, on nested folders, both ran and ``verify`` of the outer folder failed).
_HELD: dict[tuple[int, int], list[int]] = {}
#: Guards ``_HELD`` and ``_MARKS`` (two threads taking one folder's lock at once).
_GUARD = threading.RLock()
#: The line of a folder another command (process or thread) writes now.
_BUSY = (
    "another sensorgap command is writing this folder now; wait for it to finish, or write "
    "somewhere else"
)
#: How long a writer tries again to take a folder's lock held by someone (s): longer than a
#: reader's look (``locked_elsewhere``, microseconds), short beside any command's run.
READER_WAIT_S = 0.2
#: Per thread, ``held_until_done`` blocks running: a lock whose blocks ended stays held
#: until then.
_LOCAL = threading.local()


def _until_done() -> int:
    """``held_until_done`` blocks running on this thread."""
    return int(getattr(_LOCAL, "until_done", 0))


def _mine(key: tuple[int, int]) -> bool:
    """Whether this thread holds the lock of the folder ``key``."""
    entry = _HELD.get(key)
    return entry is not None and entry[2] == threading.get_ident()


def _key(folder: str | Path) -> tuple[int, int] | None:
    """(device, inode) of ``folder``, None when it is not there."""
    try:
        st = os.stat(folder)
    except OSError:
        return None
    return st.st_dev, st.st_ino


def holds_lock(folder: str | Path) -> bool:
    """Whether this process holds ``folder``'s lock (``folder_lock``): then no other
    sensorgap command writes it, and a restore folder there that no block of this process
    uses is a left-over of a killed command (``filesio.write_manifest`` removes it)."""
    key = _key(folder)
    return key is not None and _mine(key)


def locked_elsewhere(folder: str | Path) -> bool:
    """Whether another process holds ``folder``'s lock (``folder_lock``: a sensorgap
    command is writing it now), tested without waiting: a shared ``flock`` taken and
    released at once (a reader such as ``verify``; it never conflicts with another
    reader). False when this thread holds the lock, or the folder cannot be opened; True
    when another thread of this process does."""
    key = _key(folder)
    if key is not None and key in _HELD:
        return not _mine(key)
    try:
        fd = os.open(folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    except OSError:
        return False
    finally:
        os.close(fd)  # closing the only descriptor releases a lock taken
    return False


@contextmanager
def folder_lock(folder: str | Path) -> Iterator[None]:
    """Hold the exclusive lock of the existing folder ``folder`` while the block runs:
    an ``flock`` on the folder itself (no lock file in the run folder; the system drops
    it when the process ends, killed or not). Every sensorgap command that writes into a
    run folder takes it before any work, so two commands never write one folder at once
    (one's restore put its start snapshot back over the other's finished output). Taken
    again by the same thread it is shared (the job, then its search). Held by another
    process or another thread -> ``InputError`` naming the folder, at once (after at most
    ``READER_WAIT_S``: a reader, ``locked_elsewhere``, holds a shared lock for an
    instant, and a writer starting in that instant was refused as if another command
    wrote the folder; hostile round 40, R1)."""
    fd = os.open(folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    st = os.fstat(fd)
    key = (st.st_dev, st.st_ino)
    with _GUARD:
        shared = _mine(key)
        if shared:
            os.close(fd)
            _HELD[key][1] += 1
        elif key in _HELD:  # another thread's call
            os.close(fd)
            raise InputError(folder, "", _BUSY)
    if not shared:
        deadline = time.monotonic() + READER_WAIT_S
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                if time.monotonic() >= deadline:
                    os.close(fd)
                    raise InputError(folder, "", _BUSY) from None
                time.sleep(0.01)
        with _GUARD:
            _HELD[key] = [fd, 1, threading.get_ident()]
    try:
        yield
    finally:
        with _GUARD:
            entry = _HELD[key]
            entry[1] -= 1
            if entry[1] == 0 and not _until_done():
                del _HELD[key]
                os.close(entry[0])
                _drop_marks(key)


@contextmanager
def held_until_done() -> Iterator[None]:
    """Every folder lock taken while the block runs stays held until it ends (a command:
    the search of ``sensorgap search`` locks its folder, and the command still writes
    its manifest after). Per thread."""
    _LOCAL.until_done = _until_done() + 1
    try:
        yield
    finally:
        _LOCAL.until_done = _until_done() - 1
        if not _until_done():
            me = threading.get_ident()
            with _GUARD:
                for check in [k for k in _RECHECKS if k[0] == me]:
                    del _RECHECKS[check]  # the command ended: none is left for a later one
                for key, entry in list(_HELD.items()):
                    if entry[1] == 0 and entry[2] == me:
                        del _HELD[key]
                        os.close(entry[0])
                        _drop_marks(key)


#: The bytes of a folder's writing marker (``writing``): a command writing some files
#: there, one certifying the folder (its manifest lists everything below it).
WRITES, CERTIFIES = 0, 1
#: Folders below a certifying command's own looked at for other commands' markers at
#: most: ``filesio.MAX_OUT_ENTRIES``, the entries a certified folder may hold (a test
#: keeps them equal). One with more folders is refused (hostile round 40, F2: the walk
#: stopped after 20,000 folders, and a command writing below them was not seen).
MAX_MARKED_FOLDERS = 100_000
#: The markers this process holds: ((device, inode) of the folder, byte) -> (descriptor,
#: the thread that holds it).
_MARKS: dict[tuple[tuple[int, int], int], tuple[int, int]] = {}
#: Checks a command passed before its work, repeated once its folder is marked
#: (``recheck_when_marked``): (thread, absolute path of the folder) -> the check.
_RECHECKS: dict[tuple[int, str], Callable[[], None]] = {}
#: ``struct flock`` of 64-bit Linux: l_type, l_whence, l_start, l_len, l_pid (+ padding).
_FLOCK = struct.Struct("hhqqi4x")
#: Open-file-description locks exist (Linux 3.15 and later, 64-bit): elsewhere no marker
#: is taken nor looked for (the ``flock`` of each folder still applies).
_MARKERS = sys.platform == "linux" and hasattr(fcntl, "F_OFD_SETLK") and sys.maxsize > 2**32


def recheck_when_marked(folder: str | Path, check: Callable[[], None]) -> None:
    """Repeat ``check`` (it raises ``InputError`` to refuse) once ``writing`` has marked
    ``folder``, in this command. ``filesio.refuse_inside_certified`` passes before the
    command's work; another command certifying a folder above may finish (its manifest
    written, its marker gone) before this one marks its own: looked at again after the
    marker, one of the two always sees the other (hostile round 37's F1, replayed: the
    near field into P/sub passed while the corridor into P was still running, and was
    written into P after P's manifest)."""
    _RECHECKS[threading.get_ident(), os.path.abspath(folder)] = check


def _drop_marks(key: tuple[int, int]) -> None:
    """Release this thread's markers on the folder ``key`` (its lock was released)."""
    for byte in (WRITES, CERTIFIES):
        held = _MARKS.get((key, byte))
        if held is not None and held[1] == threading.get_ident():
            del _MARKS[key, byte]
            os.close(held[0])


def _open_folder(folder: str | Path) -> int | None:
    """A read-only descriptor of the folder ``folder``, None when it cannot be opened."""
    try:
        return os.open(folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    except OSError:
        return None


def _marked_elsewhere(folder: str | Path, lock_bytes: tuple[int, ...]) -> bool:
    """Whether another process holds a marker of ``folder`` on one of ``lock_bytes``
    (``F_OFD_GETLK``: would an exclusive lock of that byte conflict), or another thread of
    this process does. A byte this thread marks itself is not looked at (its own marker
    would answer). False when the folder cannot be opened or its file system has no such
    locks."""
    fd = _open_folder(folder)
    if fd is None:
        return False
    try:
        st = os.fstat(fd)
        key = (st.st_dev, st.st_ino)
        for byte in lock_bytes:
            held = _MARKS.get((key, byte))
            if held is not None:
                if held[1] != threading.get_ident():
                    return True
                continue
            probe = _FLOCK.pack(fcntl.F_WRLCK, os.SEEK_SET, byte, 1, 0)
            found = _FLOCK.unpack(fcntl.fcntl(fd, fcntl.F_OFD_GETLK, probe))
            if found[0] != fcntl.F_UNLCK:
                return True
    except OSError:
        return False
    finally:
        os.close(fd)
    return False


def _busy_nested(folder: Path, certifies: bool) -> tuple[str, Path] | None:
    """(how, where) of the nearest other command's marker that clashes with writing
    ``folder``: a folder above it or itself being certified ("inside"); for a certifying
    command also the folder itself being written or any folder below it (not through
    symbolic links) being written or certified ("holds"), or more folders below it than
    ``MAX_MARKED_FOLDERS`` ("crowded"). None when there is none."""
    try:
        where = folder.resolve()
    except (OSError, RuntimeError):  # a loop of links: the path as given
        where = Path(os.path.abspath(folder))
    for above in (where, *where.parents):
        if _marked_elsewhere(above, (CERTIFIES,)):
            return "inside", above
    if not certifies:
        return None
    if _marked_elsewhere(where, (WRITES,)):
        return "holds", where
    seen = 0
    for dirpath, dirnames, _files in os.walk(where):
        for name in dirnames:
            sub = Path(dirpath) / name
            if not sub.is_symlink() and _marked_elsewhere(sub, (WRITES, CERTIFIES)):
                return "holds", sub
        seen += len(dirnames)
        if seen > MAX_MARKED_FOLDERS:
            return "crowded", where
    return None


@contextmanager
def writing(folder: str | Path, certifies: bool) -> Iterator[None]:
    """Mark the existing folder ``folder`` as being written by this command while the
    block runs (see the module docstring; taken once every refusal of the command
    passed, just before it writes), and refuse (``InputError`` naming the folder, the
    marker released) when another command's marker clashes (``_busy_nested``): a folder
    above being certified, or, ``certifies``, one below being written. Two commands
    starting at once on nested folders may both be refused, never both let through (each
    marks before it looks). A marker of a folder whose lock this process holds stays
    until that lock is released (``folder_lock``, ``held_until_done``: the command still
    writes its manifest after the block)."""
    fd = _open_folder(folder) if _MARKERS else None
    if fd is None:  # no marker here (the command's own write reports a missing folder)
        yield
        return
    st = os.fstat(fd)
    key = (st.st_dev, st.st_ino)
    mine = (key, CERTIFIES if certifies else WRITES)
    me = threading.get_ident()
    with _GUARD:
        held = _MARKS.get(mine)
        if held is not None and held[1] != me:  # another thread writes this very folder
            os.close(fd)
            raise InputError(folder, "", _BUSY)
        new = held is None
        if not new:
            os.close(fd)
        else:
            try:
                shared = _FLOCK.pack(fcntl.F_RDLCK, os.SEEK_SET, mine[1], 1, 0)
                fcntl.fcntl(fd, fcntl.F_OFD_SETLK, shared)
            except OSError:  # a file system without such locks: no marker
                os.close(fd)
                fd = -1
            else:
                _MARKS[mine] = (fd, me)
    if fd == -1:
        yield
        return

    def release() -> None:
        if new:
            with _GUARD:
                os.close(_MARKS.pop(mine)[0])

    try:
        busy = _busy_nested(Path(folder), certifies)
        if busy is not None:
            how, where = busy
            if how == "inside":
                why = (
                    f"lies inside {where}, which another sensorgap command is writing now (it "
                    "certifies that folder when it ends, and its manifest.json would not "
                    "list these files): write somewhere outside it, or wait until that "
                    "command ends"
                )
            elif how == "crowded":
                why = (
                    f"holds more than {MAX_MARKED_FOLDERS:,} folders: whether another "
                    "sensorgap command is writing one of them cannot be told; write into a "
                    "new folder"
                )
            else:
                why = (
                    f"holds {where}, which another sensorgap command is writing now (this "
                    "command would certify its files half-written): write somewhere else, "
                    "or wait until that command ends"
                )
            raise InputError(folder, "", why)
        check = _RECHECKS.pop((me, os.path.abspath(folder)), None)
        if check is not None:
            check()
    except BaseException:
        release()
        raise
    try:
        yield
    finally:
        if not _mine(key) and mine in _MARKS:  # (held: released with the lock)
            release()
