"""Crash-safe file output: write to a temporary file in the target folder, then rename.

A reader never sees a half-written file: either the old content or the new one.
"""

from __future__ import annotations

import os
import secrets
import stat
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path

from sensorgap.errors import InputError


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success rename it onto ``path``.

    Use for writers that want a file name (``np.savez``, ``matplotlib.savefig``). On an
    exception the temporary file is removed and ``path`` is untouched.
    """
    target = Path(path)
    try:
        mode: int | None = os.lstat(target).st_mode
    except OSError:
        mode = None
    if mode is not None and stat.S_ISDIR(mode):  # the rename would fail: name the file
        raise InputError(target, "", "is a folder; give the path of a file")
    if mode is not None and not stat.S_ISREG(mode):
        # the rename would replace the node itself: a device (/dev/null, /dev/full as
        # root), a pipe, or a symbolic link such as /dev/stdout instead of its target
        raise InputError(
            target,
            "",
            "not a regular file (a symbolic link, device, pipe or socket): an output is "
            "written to a temporary file and renamed onto its path, which would replace "
            "it; give the path of a regular file",
        )
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        tmp = _create_temporary(target)
    except OSError as exc:
        raise _naming(exc, target, None) from None
    try:
        yield tmp
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, target)
    except BaseException as exc:
        tmp.unlink(missing_ok=True)
        if isinstance(exc, OSError):
            raise _naming(exc, target, tmp) from None
        raise


#: The random part of a temporary file's name (as ``tempfile.mkstemp``'s: 8 of these;
#: ``filesio.is_own_temporary`` recognises them).
_NAME_CHARS = "abcdefghijklmnopqrstuvwxyz0123456789_"


def _create_temporary(target: Path) -> Path:
    """A new empty file ``.<name>.XXXXXXXX.tmp<suffix>`` beside ``target``, created with
    mode 0o666 as ``open(..., "w")`` does, so the user's umask (and a folder's default
    ACL) decides its permissions: ``umask 077`` keeps outputs private, 022 shares them.
    (``tempfile.mkstemp`` creates 0600, which was then widened to 0644 whatever the
    umask.)"""
    for _ in range(100):
        rand = "".join(secrets.choice(_NAME_CHARS) for _ in range(8))
        tmp = target.parent / f".{target.name}.{rand}.tmp{target.suffix}"
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o666)
        except FileExistsError:
            continue
        os.close(fd)
        return tmp
    raise FileExistsError(f"no free temporary name beside {target}")


def _naming(exc: OSError, target: Path, tmp: Path | None) -> OSError:
    """``exc`` naming the output file ``target`` where it named the hidden temporary file
    or no file at all (a failed write, a full disk: "output: cannot write or read: No
    space left on device" said nothing of which file); a copy's destination
    (``filename2`` of ``shutil.copyfile``) likewise."""
    if exc.filename is None or _is_temporary_of(exc.filename, target, tmp):
        exc.filename = str(target)
        exc.filename2 = None
    elif exc.filename2 is not None and _is_temporary_of(exc.filename2, target, tmp):
        exc.filename2 = str(target)
    return exc


def _is_temporary_of(name: object, target: Path, tmp: Path | None) -> bool:
    """Whether the file ``name`` (of an ``OSError``) is ``tmp`` or another temporary file
    of ``target`` (``.<name>.XXXXXXXX.tmp...`` beside it, e.g. one ``_create_temporary``
    could not create)."""
    if not isinstance(name, str | bytes):
        return False
    path = Path(os.fsdecode(name))
    return (tmp is not None and path == tmp) or (
        path.parent == target.parent
        and path.name.startswith(f".{target.name}.")
        and ".tmp" in path.name
    )


def atomic_write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically; returns the path."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return Path(path)


def utf8(text: str) -> bytes:
    """``text`` as UTF-8 for an output file. A path that is not valid UTF-8 reaches text as
    lone surrogates (Python's ``surrogateescape``); they are written as ``\\udcXX`` escapes
    (readable, and no output fails on a folder name: the byte itself is in no encoding)."""
    return text.encode("utf-8", errors="backslashreplace")


def atomic_write_text(path: str | Path, text: str) -> Path:
    """Write UTF-8 ``text`` (``utf8``) with ``\\n`` line ends to ``path`` atomically;
    returns the path."""
    return atomic_write_bytes(path, utf8(text))


@contextmanager
def removed_on_error(folder: str | Path) -> Iterator[None]:
    """On an exception or an interrupt (Ctrl-C, SIGTERM), remove every file below
    ``folder`` that was not there before, and the folders created, so a failed or stopped
    command leaves nothing half-written (e.g. a coverage.npz without its png and summary,
    or the first figures of a report that its manifest does not list). Files that existed
    are kept. (Resumable work, the search store, is not written under this guard.)"""
    root = Path(folder)
    existed = root.is_dir()
    before = {p for p in root.rglob("*")} if existed else set()
    try:
        yield
    except BaseException:
        if root.is_dir():
            new = sorted(
                (p for p in root.rglob("*") if p not in before),
                key=lambda p: len(p.parts),
                reverse=True,
            )
            for p in new:
                with suppress(OSError):
                    if p.is_symlink() or p.is_file():
                        p.unlink()
                    elif p.is_dir():
                        p.rmdir()
            if not existed:
                with suppress(OSError):
                    root.rmdir()
        raise
