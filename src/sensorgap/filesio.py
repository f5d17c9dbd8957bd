"""Deterministic, atomic writers for the file formats sensorgap emits (CSV, JSON, NPZ).

Same inputs -> byte-identical files: fixed float formatting, sorted JSON keys, zip entries
with a fixed timestamp. Every writer goes through ``sensorgap.atomic``.
"""

from __future__ import annotations

import io
import json
import math
import os
import re
import shutil
import stat
import zipfile
from collections.abc import Callable, Collection, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sensorgap.atomic import atomic_write_bytes, utf8
from sensorgap.errors import InputError, cut_name
from sensorgap.locks import holds_lock, locked_elsewhere, recheck_when_marked

_FIXED_ZIP_TIME = (1980, 1, 1, 0, 0, 0)


def _check_finite(name: str, values: NDArray[Any]) -> None:
    if values.dtype.kind == "f" and not np.all(np.isfinite(values)):
        raise ValueError(f"refusing to write non-finite values in {name!r}")


def format_float(v: float) -> str:
    """Shortest round-trip representation of a finite float (``repr``), ``-0`` -> ``0``."""
    if not math.isfinite(v):
        raise ValueError(f"refusing to write a non-finite number: {v!r}")
    return repr(float(v) + 0.0)


def csv_bytes(columns: Sequence[str], data: Sequence[NDArray[Any]]) -> bytes:
    """CSV text (``\\n`` line ends) of equally long columns; floats in round-trip form."""
    for name, col in zip(columns, data, strict=True):
        _check_finite(name, np.asarray(col))
    # each column as text: floats as ``format_float`` writes them (finite: checked above)
    text = [
        list(map(repr, (c + 0.0).tolist())) if c.dtype.kind == "f" else list(map(str, c.tolist()))
        for c in (np.asarray(c) for c in data)
    ]
    lines = [",".join(columns), *map(",".join, zip(*text, strict=True))]
    return utf8("\n".join(lines) + "\n")


def write_csv(path: str | Path, columns: Sequence[str], data: Sequence[NDArray[Any]]) -> Path:
    """Write a CSV atomically (see ``csv_bytes``)."""
    return atomic_write_bytes(path, csv_bytes(columns, data))


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return obj.as_posix()
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


def json_bytes(obj: Any) -> bytes:
    """Sorted, indented JSON; NaN/inf are refused (``allow_nan=False``)."""
    text = json.dumps(obj, indent=2, sort_keys=True, allow_nan=False, default=_json_default)
    return utf8(text + "\n")


def write_json(path: str | Path, obj: Any) -> Path:
    """Write JSON atomically (see ``json_bytes``)."""
    return atomic_write_bytes(path, json_bytes(obj))


def write_npz(path: str | Path, arrays: Mapping[str, NDArray[Any]]) -> Path:
    """Write arrays as a compressed ``.npz`` with fixed zip timestamps (byte-identical)."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for name in sorted(arrays):
            arr = np.ascontiguousarray(arrays[name])
            _check_finite(name, arr)
            member = io.BytesIO()
            np.lib.format.write_array(member, arr, allow_pickle=False)
            info = zipfile.ZipInfo(f"{name}.npy", date_time=_FIXED_ZIP_TIME)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            zf.writestr(info, member.getvalue())
    return atomic_write_bytes(path, buf.getvalue())


MANIFEST_NAME = "manifest.json"
_JOURNAL_SUFFIXES = ("-journal", "-wal", "-shm")
_SHA256_HEX = frozenset("0123456789abcdef")


def _unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:  # which of the two would be read is not the writer's choice
            raise ValueError(f"key {key[:64]!r} appears twice in one object")
        out[key] = value
    return out


def _json_int(text: str) -> int | float:
    """A JSON integer: exact (an ``int``) within 64 bits, which is all sensorgap writes
    (counts, sizes, seeds); beyond, the nearest float (``inf`` past 1.8e308), as JSON
    readers that hold numbers as IEEE doubles do (RFC 8259, section 6). The readers'
    checks then name the field ("expected a finite number, got inf", "expected a
    positive integer"): a 400-digit rank or probability was an internal error further on
    (a float conversion), and one of more than 4,300 digits Python's ``int(str)`` limit
    (hostile round 22)."""
    digits = text.lstrip("-")
    if len(digits) <= 18 or (len(digits) <= 19 and -(2**63) <= int(text) < 2**63):
        return int(text)
    return float(text)


#: The deepest nesting of arrays and objects a JSON file of a run folder may have (sensorgap
#: writes at most 4 levels): deeper is ``RecursionError`` before parsing, on every Python
#: (the ``json`` module's own limit differs: 3.11 failed near 1,000 levels, 3.13 parses far
#: deeper), so the readers' "nested too deeply" line does not depend on the interpreter.
MAX_JSON_DEPTH = 64
_JSON_STRING = re.compile(r'"(?:[^"\\]|\\.)*"')
_JSON_BRACKET = re.compile(r"[\[\]{}]")


def json_too_deep(text: str) -> bool:
    """Whether the JSON ``text`` nests arrays and objects more than ``MAX_JSON_DEPTH``
    levels (brackets inside strings do not count)."""
    if text.count("[") + text.count("{") <= MAX_JSON_DEPTH:
        return False
    depth = 0
    for m in _JSON_BRACKET.finditer(_JSON_STRING.sub('""', text)):
        depth += 1 if m.group() in "[{" else -1
        if depth > MAX_JSON_DEPTH:
            return True
    return False


def loads_json(text: str | bytes) -> Any:
    """Parse JSON as sensorgap's readers of run folders do: an object naming a key twice
    is ``ValueError`` (Python's ``json`` would keep the last one silently); an integer
    beyond 64 bits is read as a float (``_json_int``); nesting deeper than
    ``MAX_JSON_DEPTH`` is ``RecursionError`` (``json_too_deep``)."""
    if isinstance(text, bytes | bytearray):
        text = text.decode("utf-8")
    if json_too_deep(text):
        raise RecursionError(
            f"maximum recursion depth exceeded: arrays and objects nested more than "
            f"{MAX_JSON_DEPTH} levels"
        )
    return json.loads(text, object_pairs_hook=_unique_keys, parse_int=_json_int)


#: The largest earlier JSON file a command reads back to keep its fields
#: (``previous_json_object``): as ``search.runfolder.MAX_JSON_BYTES``.
MAX_PREVIOUS_JSON_BYTES = 20_000_000


def previous_json_object(path: Path) -> dict[str, Any]:
    """The JSON object of the file ``path`` a command is about to rewrite (``run.json``),
    read to keep its other fields: ``{}`` when it is absent, not a regular file, larger
    than ``MAX_PREVIOUS_JSON_BYTES``, unreadable, not JSON, nested too deeply
    (``loads_json``) or not an object. Hostile round 32: a run.json nested 200,001 levels
    was read by plain ``json.loads`` and a resumed search stopped with an internal
    RecursionError."""
    try:
        st = path.stat()
        if not stat.S_ISREG(st.st_mode) or st.st_size > MAX_PREVIOUS_JSON_BYTES:
            return {}
        data = loads_json(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError):
        return {}
    return data if isinstance(data, dict) else {}


#: The names ``sensorgap.atomic`` gives its temporary files: ``.NAME.<8 random>.tmp.EXT``
#: (``tempfile.mkstemp``'s random part: 8 of ``a-z0-9_``).
_OWN_TEMPORARY = re.compile(r"\..+\.[a-z0-9_]{8}\.tmp(\.[^/]*)?")


def regular_file_size(
    path: Path, at_most: int | None = None, noun: str = "file", hint: str = ""
) -> int:
    """The size (bytes) of the file a command is about to read, which must be a regular
    file (a link to one is fine): a named pipe blocked the reader forever, a device
    never ends (hostile round 26), so anything else is an ``InputError`` naming it. A
    missing file raises ``FileNotFoundError`` as the read would. ``at_most``: the
    largest size the reader accepts (bytes), checked before it reads: "<noun> is N bytes;
    at most M allowed<hint>"."""
    st = path.stat()
    if not stat.S_ISREG(st.st_mode):
        raise InputError(
            path, "", "not a regular file (a folder, named pipe, socket or device): expected a file"
        )
    if at_most is not None and st.st_size > at_most:
        raise InputError(path, "", f"{noun} is {st.st_size} bytes; at most {at_most} allowed{hint}")
    return st.st_size


def is_own_temporary(name: str) -> bool:
    """Whether a file name is one of ``sensorgap.atomic``'s own temporary files (the only
    files sensorgap ever deletes from an output folder: a user's ``notes.tmp`` is not)."""
    return _OWN_TEMPORARY.fullmatch(name) is not None


def not_a_run_folder(path: Path) -> str:
    """Why ``path``, which is no folder, cannot be read as a run folder: it is something
    else (a file, a broken link) or it does not exist (hostile round 35: a file given to
    ``report --run`` was said not to exist)."""
    if os.path.lexists(path):
        return "is not a folder: give a run folder"
    return "run folder does not exist"


def is_temporary(name: str) -> bool:
    """Whether a file name is a temporary file of ``sensorgap.atomic`` (``.NAME.*.tmp*``)
    or of an interrupted write (``*.tmp``), or an SQLite journal (``-journal``, ``-wal``,
    ``-shm``): never part of a finished run folder."""
    return (
        (name.startswith(".") and ".tmp" in name)
        or name.endswith(".tmp")
        or name.endswith(_JOURNAL_SUFFIXES)
    )


def _in_temporary_folder(rel: str) -> bool:
    """Whether the relative path ``rel`` lies below a temporary folder (a guarded
    command's restore folder, ``atomic.RESTORE_PREFIX``): never part of a run folder."""
    return any(is_temporary(part) for part in rel.split("/")[:-1])


#: How ``verify``'s line for a restore folder left by a killed command ends.
_RESTORE_BY_HAND = "move them back by hand to restore the folder, or delete it"
#: How ``verify``'s line for the restore folder of a command running now ends.
_RESTORE_IN_USE = "verify it when that command ends"


def _is_restore_folder(path: Path) -> bool:
    """Whether ``path`` is named exactly as ``atomic.removed_on_error`` names its restore
    folders (``RESTORE_PREFIX``, ``tempfile.mkdtemp``'s 8 random characters, ``.tmp``)
    and holds only what it puts there: files named by numbers (``0``, ``1``, ...) and its
    index (``atomic.RESTORE_INDEX``). A user's folder that merely imitates the name (it
    holds ``data.txt``) is not one."""
    import os

    from sensorgap.atomic import RESTORE_INDEX, RESTORE_PREFIX

    if not re.fullmatch(re.escape(RESTORE_PREFIX) + r"[a-z0-9_]{8}\.tmp", path.name):
        return False
    try:
        with os.scandir(path) as it:
            return all(
                (e.name.isdigit() or e.name == RESTORE_INDEX) and e.is_file(follow_symlinks=False)
                for e in it
            )
    except OSError:
        return False


def _is_active_restore(path: Path) -> bool:
    """Whether ``path`` is the restore folder of a guarded command running in this
    process (removed when its block ends)."""
    import os

    from sensorgap.atomic import ACTIVE_RESTORE_FOLDERS

    return os.path.abspath(path) in ACTIVE_RESTORE_FOLDERS


def _is_leftover_restore(path: Path) -> bool:
    """Whether ``path`` is a restore folder of ``atomic.removed_on_error``
    (``_is_restore_folder``) that no command of this process is using, in a folder whose
    lock this process holds (``locks.holds_lock``: no other command is writing there, so
    a killed command left it; another process's restore folder is never removed)."""
    return _is_restore_folder(path) and not _is_active_restore(path) and holds_lock(path.parent)


def _uncertifiable(root: Path, entries: list[tuple[str, str]]) -> str | None:
    """The first of ``entries`` (``_walk``'s, below ``root``) that would make a manifest
    written now fail ``verify``: a named pipe, socket or device file, or a file that
    looks temporary (``*.tmp``, a journal, a file below a ``*.tmp`` folder) that
    ``write_manifest`` would neither list nor remove (this process's restore folder, a
    killed command's and sensorgap's own temporary files excepted): its relative path
    and what it is; or None."""
    # restore folders: this process's (its block removes it), a killed command's
    # (write_manifest removes it under the folder's lock) or another running command's
    # (never listed; its own command removes it)
    skipped: list[str] = []
    for rel, kind in entries:
        if any(rel.startswith(f"{s}/") for s in skipped):
            continue
        if kind == "dir" and _is_restore_folder(root / rel):
            skipped.append(rel)
        elif kind == "other":
            return f"{rel}, a named pipe, socket or device file"
        elif kind == "file" and rel != MANIFEST_NAME:
            name = rel.rsplit("/", 1)[-1]
            if _in_temporary_folder(rel) or (is_temporary(name) and not is_own_temporary(name)):
                return f"{rel}, named like a left-over temporary or journal file"
    return None


def refuse_uncertifiable(folder: str | Path, what: str = "--out") -> None:
    """Before a command writes ``folder/manifest.json``: refused (``InputError`` naming
    ``what``) when the folder holds an entry ``verify`` would reject in the new manifest
    (``_uncertifiable``: a named pipe or socket, a ``*.tmp`` folder or file of the
    user's; symbolic links are refused by each command's own checks), so no command
    exits 0 with a folder that fails its own ``verify``. A folder that does not exist
    passes."""
    from sensorgap.errors import InputError

    root = Path(folder)
    if not root.is_dir():
        return
    why = _uncertifiable(root, _walk(root))
    if why is not None:
        raise InputError(
            what,
            "",
            f"{root} holds {why}: a run folder holds only regular files and folders, and "
            "verify would reject the manifest written over it; move it away or give "
            "another folder",
        )


def _walk(root: Path, unreadable: dict[str, str] | None = None) -> list[tuple[str, str]]:
    """Every entry below ``root`` as (relative POSIX path, kind): kind is ``file``,
    ``dir``, ``link`` (a symbolic link, never followed) or ``other``; sorted. A folder that
    cannot be listed raises its ``OSError``, or with ``unreadable`` is recorded there
    (relative path, ``.`` for ``root``, -> the system's reason) and skipped: its files
    were silently absent (``verify`` called them missing)."""
    import os

    def failed(exc: OSError) -> None:
        if unreadable is None:
            raise exc
        where = Path(os.fsdecode(exc.filename)) if exc.filename is not None else root
        rel = where.relative_to(root).as_posix() if where != root else "."
        unreadable[rel] = exc.strerror or type(exc).__name__

    out: list[tuple[str, str]] = []
    for dirpath, dirnames, filenames in os.walk(root, onerror=failed, followlinks=False):
        for name in [*dirnames, *filenames]:
            full = Path(dirpath) / name
            try:
                mode = os.lstat(full).st_mode
            except OSError as exc:  # a folder that may be listed but not entered
                exc.filename = dirpath
                failed(exc)
                dirnames.clear()
                break
            kind = (
                "link"
                if stat.S_ISLNK(mode)
                else "dir"
                if stat.S_ISDIR(mode)
                else "file"
                if stat.S_ISREG(mode)
                else "other"
            )
            out.append((full.relative_to(root).as_posix(), kind))
    return sorted(out)


def _unreadable_folder(rel: str, unreadable: dict[str, str]) -> str | None:
    """The folder of ``unreadable`` that holds ``rel`` (the nearest), or None."""
    parts = rel.split("/")[:-1]
    for i in range(len(parts), 0, -1):
        folder = "/".join(parts[:i])
        if folder in unreadable:
            return folder
    return "." if "." in unreadable else None


def _sha256_file(path: Path) -> tuple[int, str]:
    import hashlib

    h, size = hashlib.sha256(), 0
    with open(path, "rb") as fh:
        while chunk := fh.read(1 << 20):
            h.update(chunk)
            size += len(chunk)
    return size, h.hexdigest()


def write_manifest(folder: str | Path, rewrites: tuple[str, ...] | None = None) -> Path:
    """Write ``folder/manifest.json``: every regular file below ``folder`` (sorted relative
    POSIX paths) with its size in bytes and SHA-256, so an assessor can verify that nothing
    was changed or lost. Deterministic: no timestamps. Left-over temporary files of
    ``sensorgap.atomic`` (from an interrupted earlier command, ``is_own_temporary``) and
    restore folders no running command uses (``atomic.RESTORE_PREFIX``, left by a killed
    one) are removed, the files below a temporary folder never listed, other
    temporary-looking files left alone and unlisted; database
    journals, symbolic links and the manifest itself are left out (``verify`` reports
    all but the manifest). With ``rewrites`` (a command adding to a folder, see
    ``refuse_if_changed``) the entries of files lost since that the command does not
    write stay as recorded. A folder holding what ``verify`` would reject whatever the
    manifest says (``_uncertifiable``: a named pipe, a user's ``*.tmp``) raises
    ``InputError`` before anything is written or removed."""
    root = Path(folder)
    files: dict[str, dict[str, Any]] = {}
    if rewrites is not None and (root / MANIFEST_NAME).is_file():
        # a command adding to a certified folder: files it does not write that were lost
        # since stay listed (as recorded), so verify reports them (refuse_if_changed)
        for rel, meta in read_manifest(root).items():
            if not _written_by(rel, rewrites) and not (root / rel).exists():
                files[rel] = meta
    entries = _walk(root)
    why = _uncertifiable(root, entries)  # a folder that its own verify would reject
    if why is not None:
        from sensorgap.errors import InputError

        raise InputError(
            root / MANIFEST_NAME,
            "",
            f"not written: the folder holds {why}, which verify rejects (a run folder "
            "holds only regular files and folders); move it away and run the command again",
        )
    for rel, kind in entries:  # a killed command's restore folder (atomic.removed_on_error)
        if kind == "dir" and _is_leftover_restore(root / rel):
            shutil.rmtree(root / rel, ignore_errors=True)
    for rel, kind in entries:
        p = root / rel
        if kind != "file" or rel == MANIFEST_NAME or _in_temporary_folder(rel):
            continue
        if is_temporary(p.name):
            if is_own_temporary(p.name):  # never a user's file that merely looks like one
                p.unlink(missing_ok=True)
            continue
        size, sha = _sha256_file(p)
        files[rel] = {"bytes": size, "sha256": sha}
    data = json_bytes({"algorithm": "sha256", "files": dict(sorted(files.items()))})
    if len(data) > MAX_MANIFEST_BYTES:  # verify would refuse to read it (read_manifest)
        from sensorgap.errors import InputError

        raise InputError(
            root / MANIFEST_NAME,
            "",
            f"not written: it would be {len(data)} bytes, and verify reads at most "
            f"{MAX_MANIFEST_BYTES // 1_000_000} MB ({len(files)} files; long paths make it "
            "larger); move files away and run the command again",
        )
    written = atomic_write_bytes(root / MANIFEST_NAME, data)
    found = certified_parent(root)
    if found is not None and holds_lock(found[0]):
        # a command into OUT/<vehicle> or RUN/nearfield (holding the parent's lock): the
        # parent certified again
        write_manifest(found[0], (f"{found[1]}/",))
    return written


#: Sub-folders of a search run that a command may add to it for its report, by command:
#: ``nearfield --out RUN/nearfield``, ``coverage --out RUN/coverage/<name>``.
REPORT_INPUTS = {"nearfield": ("nearfield",), "coverage": ("coverage", "*")}


def _report_input(rel: str, command: str | None) -> bool:
    parts = tuple(rel.split("/"))
    shapes = REPORT_INPUTS.values() if command is None else [REPORT_INPUTS.get(command, ())]
    return any(
        len(parts) == len(shape) and all(w in ("*", p) for w, p in zip(shape, parts, strict=True))
        for shape in shapes
        if shape
    )


def certified_parent(folder: str | Path, command: str | None = None) -> tuple[Path, str] | None:
    """The certified folder P that a command writing ``folder`` certifies again after its
    own manifest, with ``folder``'s path relative to it, or None:

    * a vehicle folder of a certified job (``sensorgap run``'s ``OUT/<vehicle>``: OUT's
      manifest lists ``<vehicle>/manifest.json``), and any certified sub-folder P's
      manifest lists the same way (``RUN/nearfield`` after a report);
    * a new sub-folder of a search run (P holds ``search.sqlite``) that its report reads,
      written by its own command (``REPORT_INPUTS``; ``command`` None: either):
      ``nearfield --out RUN/nearfield``, ``coverage --out RUN/coverage/car_fog_50``.

    P's manifest certifies every file below P: a command writing into such a folder locks
    P as well, checks P's other files, and certifies P again after its own manifest
    (``write_manifest``), so ``verify P`` still passes (a near field added to a run was
    unlisted in its manifest until the next report)."""
    from sensorgap.errors import InputError

    root = Path(os.path.abspath(folder))
    for parent in (root.parent, root.parent.parent):
        if parent == root or not (parent / MANIFEST_NAME).is_file():
            continue
        try:
            listed = read_manifest(parent)
        except (InputError, OSError, ValueError):
            return None  # not certified (verify reports a damaged manifest)
        rel = root.relative_to(parent).as_posix()
        if f"{rel}/{MANIFEST_NAME}" in listed:
            return parent, rel
        if (parent / "search.sqlite").is_file() and _report_input(rel, command):
            return parent, rel
        return None  # the nearest certified folder decides
    return None


def bad_entry_name(rel: object) -> str | None:
    """Why an entry name of a folder's index (a manifest's, catalog.json's ``files``) is
    not a relative path inside the folder (None: fine)."""
    if not isinstance(rel, str) or not rel:
        return "must be a non-empty relative path"
    parts = rel.split("/")
    if rel.startswith("/") or (len(rel) > 1 and rel[1] == ":"):
        return "must be a relative POSIX path inside the folder, not an absolute path"
    if "\\" in rel:
        return "must be a relative POSIX path (a backslash is no part of a run folder's names)"
    if any(part in ("", ".", "..") for part in parts):
        return "must be a normalised relative path inside the folder (no '..', '.' or '//')"
    if "\x00" in rel:
        return "must not contain NUL"
    return None


#: The largest ``manifest.json`` read, bytes (docs/limits.md): about 120 bytes a file, so
#: room for the ``MAX_OUT_ENTRIES`` entries of a folder with long paths; larger is not
#: one sensorgap wrote.
MAX_MANIFEST_BYTES = 100_000_000


def read_manifest(folder: str | Path) -> dict[str, dict[str, Any]]:
    """The ``files`` of ``folder/manifest.json``, checked: a JSON object whose ``files``
    maps relative paths inside the folder to ``{"bytes": int, "sha256": hex}``. Anything
    else -> ``InputError`` naming the manifest and the field."""
    from sensorgap.errors import InputError

    path = Path(folder) / MANIFEST_NAME
    try:
        if path.stat().st_size > MAX_MANIFEST_BYTES:
            raise InputError(
                path,
                "",
                f"larger than {MAX_MANIFEST_BYTES // 1_000_000} MB; not a sensorgap manifest",
            )
        data = loads_json(path.read_bytes().decode("utf-8"))
    except (UnicodeDecodeError, ValueError) as exc:
        raise InputError(path, "", f"malformed manifest: not JSON ({exc})") from None
    except RecursionError:
        raise InputError(path, "", "malformed manifest: nested too deeply") from None
    if not isinstance(data, dict) or not isinstance(data.get("files"), dict):
        raise InputError(
            path,
            "files",
            "malformed manifest: expected an object with "
            "'files' mapping each relative path to its bytes and sha256",
        )
    if data.get("algorithm") != "sha256":
        raise InputError(path, "algorithm", f"must be sha256, got {data.get('algorithm')!r}")
    files: dict[str, dict[str, Any]] = data["files"]
    for rel, meta in files.items():
        why = bad_entry_name(rel)
        if why:
            raise InputError(path, f"files[{rel!r}]", why)
        ok = (
            isinstance(meta, dict)
            and isinstance(meta.get("bytes"), int)
            and not isinstance(meta.get("bytes"), bool)
            and meta["bytes"] >= 0
            and isinstance(meta.get("sha256"), str)
            and len(meta["sha256"]) == 64
            and set(meta["sha256"]) <= _SHA256_HEX
        )
        if not ok:
            raise InputError(
                path,
                f"files[{rel!r}]",
                'expected {"bytes": a non-negative integer, "sha256": 64 lowercase hex digits}',
            )
    return files


def _written_by(rel: str, rewrites: tuple[str, ...]) -> bool:
    """Whether ``rel`` lies below one of a command's ``rewrites`` (relative POSIX paths
    or folders; ``dir/*``: that folder's direct children only)."""
    for w in rewrites:
        if w.endswith("/*"):
            head = w[:-1]
            if rel.startswith(head) and "/" not in rel[len(head) :]:
                return True
        elif rel == w.rstrip("/") or rel.startswith(w.rstrip("/") + "/"):
            return True
    return False


def remove_outputs(folder: str | Path, patterns: tuple[str, ...]) -> list[str]:
    """Remove the regular files below ``folder`` that lie under ``patterns`` (as for
    ``refuse_if_changed``) and the folders they leave empty, the folder of a ``dir/*``
    pattern included (a resumed search removing the export's maps left an empty
    ``coverage/``); symbolic links are never followed or removed, nor a folder that held
    no removed file and lies outside ``patterns``. Returns the removed files' relative
    POSIX paths, sorted."""
    root = Path(folder)
    removed = []
    emptied: set[str] = set()  # folders that held a removed file
    for rel, kind in _walk(root):
        if kind == "file" and _written_by(rel, patterns):
            (root / rel).unlink()
            removed.append(rel)
            parts = rel.split("/")[:-1]
            emptied.update("/".join(parts[:i]) for i in range(1, len(parts) + 1))
    for rel, kind in reversed(_walk(root)):  # deepest first
        if (
            kind == "dir"
            and (_written_by(rel, patterns) or rel in emptied)
            and not any((root / rel).iterdir())
        ):
            (root / rel).rmdir()
    return removed


def refuse_if_changed(folder: str | Path, rewrites: tuple[str, ...], lost_ok: bool = False) -> None:
    """Before a command adds to a folder that already has a ``manifest.json`` and then
    rewrites it: every file the manifest lists must be as recorded (and no symbolic link
    may be there), except below the paths this command writes itself (``rewrites``:
    relative POSIX paths or folders, e.g. ``report.html``, ``scenarios/``; ``coverage/*``:
    that folder's direct children only). Otherwise the new manifest would certify a file
    changed by hand, and ``verify`` would say OK. Files added since are not refused (other
    commands write into sub-folders of a run; the new manifest lists them), nor files lost
    from a sub-folder (an analysis or export part: the command degrades;
    ``write_manifest(folder, rewrites)`` keeps them listed, so ``verify`` still reports
    them); a file lost at the top of the folder (the run's own record) is. Raises
    ``InputError`` naming the first such file and how many there are; a folder without a
    manifest is not checked (nothing certified yet). ``lost_ok``: no lost file is
    refused (the main job, which writes the whole run folder and its record again)."""
    root = Path(folder)

    # a file added since (another command's outputs in a sub-folder, e.g. a job's near
    # field) is listed by the new manifest; a file of a part lost (in a sub-folder: an
    # analysis, the export) stays listed (write_manifest with the same rewrites), so
    # verify still reports it; a certified file changed, or one of the run's own record
    # at the top of the folder (ranking, summary, run.json) lost, is refused
    def refused(rel: str, why: str) -> bool:
        return (
            not _written_by(rel, rewrites)
            and not why.endswith(
                (
                    "(from an interrupted command; not in the manifest)",
                    "is not in the manifest",
                    _RESTORE_BY_HAND,
                    _RESTORE_IN_USE,
                )
            )
            and not (why.endswith(" is missing") and ("/" in rel or lost_ok))
        )

    _refuse_unmatched(
        root,
        refused,
        f"; run 'sensorgap verify {root}'",
        "writing into it would certify that; restore the file or run the command again "
        "into a fresh folder",
    )


#: Files and folders an existing ``--out`` of an analysis command may hold (a user's
#: project folder): more are refused before any work, since the command lists the folder
#: before it starts and hashes every file into its manifest (``--out /`` or ``~``).
MAX_OUT_ENTRIES = 100_000
#: Files at the top of a search run or catalog folder (``search``, ``export``).
RUN_FOLDER_FILES = ("ranking.json", "run.json", "search.sqlite", "catalog.json")


def refuse_foreign_outputs(
    folder: str | Path,
    writes: tuple[str, ...] | None,
    command: str,
    others: Collection[str] = (),
) -> None:
    """Before an analysis command (``coverage``, ``nearfield``, ``farfield``,
    ``corridor``) writes its files (``writes``, at the top of ``folder``) and a new
    manifest of every file there into an existing ``folder``: refused (``InputError``
    naming ``--out``) when the folder is another command's certified output (its
    ``manifest.json`` lists a file this command does not write: the new manifest would
    certify a file edited by hand since, and e.g. a search's ``summary.json`` would be
    overwritten), a search run or catalog without a manifest, or holds more than
    ``MAX_OUT_ENTRIES`` files and folders (counted up to that). A user's folder with other
    files is accepted (the manifest lists them), as is an earlier output of the same
    command. ``writes`` None (``paper``, ``tradeoff``, ``compare``: many outputs, named
    after the runs): only a search run or catalog is refused, with or without its
    manifest (the caller checks the rest with ``refuse_if_changed``). A symbolic link
    anywhere below ``folder`` is refused for every command (``verify`` rejects links).

    The same command run again into a folder of the user's own files that it certified
    the first time (its manifest lists every file of ``writes`` and files none of which
    is a file of another command's, ``others``, or of a run folder) goes on when those
    files are still as certified (``refuse_if_changed``): it was refused as "another
    command's outputs" (hostile round 22)."""

    from sensorgap.errors import InputError

    root = Path(folder)
    if not root.is_dir():
        return

    def refuse(why: str) -> InputError:
        return InputError(
            "--out",
            "",
            f"{root} {why}; {command} writes only into a new folder, a folder of your own "
            f"files or one it wrote before; give another --out",
        )

    for name in (*(writes or ()), MANIFEST_NAME):  # renamed onto: refused mid-way
        own = root / name
        if own.is_symlink() or (own.exists() and not own.is_file()):
            raise refuse(f"holds {name}, a symbolic link or not a regular file")
    if writes is not None and (root / MANIFEST_NAME).is_file():
        listed = read_manifest(root)
        foreign = [rel for rel in listed if rel not in writes]
        users = all(w in listed for w in writes) and not any(
            rel in others or rel in RUN_FOLDER_FILES for rel in foreign
        )
        if foreign and not users:
            raise refuse(
                f"holds the certified outputs of another command (its {MANIFEST_NAME} "
                f"lists {foreign[0]}, which {command} does not write)"
            )
        if foreign:  # its own earlier output beside the user's files: as certified?
            refuse_if_changed(root, writes)
    else:
        marker = next((n for n in RUN_FOLDER_FILES if (root / n).exists()), None)
        if marker is not None:
            raise refuse(f"holds a search run or catalog ({marker})")
    if crowded(root):
        raise refuse(f"holds more than {MAX_OUT_ENTRIES} files and folders")
    refuse_uncertifiable(root)
    # a link anywhere: verify rejects the manifest written over it (the analysis commands
    # exited 0 and their own verify failed), and a link could be renamed onto
    odd = _first_link(root)
    if odd is not None:
        raise refuse(f"holds {odd}, a symbolic link or not a regular file")


def refuse_certified_by_other(
    folder: str | Path, command: str, own: Callable[[str], bool], own_text: str
) -> None:
    """Before ``search``, ``run``, ``export``, ``paper``, ``tradeoff``, ``compare`` or
    ``report --compare`` (which add to their own earlier folder and certify it again)
    writes into an existing ``folder`` with a ``manifest.json``: refused
    (``InputError`` naming ``--out``) unless that manifest is one the command wrote,
    i.e. lists an entry ``own`` accepts (``own_text`` says which: ``search.sqlite`` for a
    search, ``<vehicle>/manifest.json`` for a job's OUT, ``cli.OWN_OUTPUT``'s file for the
    others). Another command's certified output (a ``coverage`` folder, a catalog
    exported elsewhere) was accepted, its files overwritten (``summary.json``) or
    certified again beside the new ones, as the analysis commands refuse
    (``refuse_foreign_outputs``). A folder without a manifest passes (the command's other
    checks apply)."""
    from sensorgap.errors import InputError

    root = Path(folder)
    if not root.is_dir() or not (root / MANIFEST_NAME).is_file():
        return
    listed = read_manifest(root)
    if any(own(rel) for rel in listed):
        return
    first = next(iter(sorted(listed)), None)
    lists = f"lists {first}" if first is not None else "lists no file"
    raise InputError(
        "--out",
        "",
        f"{root} holds the certified outputs of another command (its {MANIFEST_NAME} "
        f"{lists} and no {own_text}); {command} writes only into a new folder, a folder of "
        f"your own files or one it wrote before; give another --out",
    )


def _certified_above(folder: Path) -> tuple[Path, str] | None:
    """The nearest folder above ``folder`` (resolved: a symbolic link on the way is
    followed, as the command's writes would be) that is certified, with the first file its
    manifest lists (None: none is). Certified: it holds a ``manifest.json`` that
    ``read_manifest`` accepts (a sensorgap manifest; another tool's ``manifest.json``, a
    web app's, is not one, nor is a damaged one, which ``verify`` reports anyway)."""
    from sensorgap.errors import InputError

    try:
        where = folder.resolve()
    except (OSError, RuntimeError):  # a loop of links: the written path as given
        where = Path(os.path.abspath(folder))
    for parent in where.parents:
        if not (parent / MANIFEST_NAME).is_file():
            continue
        try:
            listed = read_manifest(parent)
        except (InputError, OSError, ValueError):
            continue
        return parent, next(iter(sorted(listed)), "no file")
    return None


def refuse_certified_out(folder: str | Path, command: str) -> None:
    """Before ``evaluate`` or ``probe --out`` writes its files (which no manifest lists)
    into ``folder``: refused (``InputError`` naming ``--out``) when the folder is certified
    (it holds ``manifest.json``: a search run, a catalog, another command's output) or is
    a search run or catalog without one (``RUN_FOLDER_FILES``), or lies anywhere inside a
    certified folder (``_certified_above``: ``RUN/scenarios/x``, ``RUN/coverage/new``,
    existing or not). Before, the command exited 0 and ``verify`` of the folder then
    failed ("evaluation.json is not in the manifest"). A folder of a user's own files, or
    a new one outside any certified folder, passes."""
    from sensorgap.errors import InputError

    root = Path(folder)
    if root.is_dir():
        marker = next((n for n in (MANIFEST_NAME, *RUN_FOLDER_FILES) if (root / n).exists()), None)
        if marker is None and (root / MANIFEST_NAME).is_symlink():
            marker = MANIFEST_NAME
        if marker is not None:
            raise InputError(
                "--out",
                "",
                f"{root} holds {marker}: a certified folder (a search run, a catalog or "
                f"another command's output); {command} writes files no manifest lists, so "
                "its verify would fail: give another --out (a new folder or one of your own "
                "files)",
            )
    refuse_inside_certified(root, command)


def refuse_inside_certified(folder: str | Path, command: str) -> None:
    """An ``--out`` inside a certified folder (``_certified_above``: a search run, a
    catalog, a job, another command's output; existing or new, a symbolic link on the way
    followed) is refused (``InputError`` naming ``--out``) unless the command certifies
    that folder again (``certified_parent``: a job's vehicle folder, a run's near field or
    coverage map): its files would lie in a folder whose manifest does not list them, and
    ``verify`` of that folder would fail (``paper --out RUN/p``, ``export --out
    RUN/cat`` did, hostile round fourteen). Repeated once the command marks its folder
    (``locks.recheck_when_marked``: a folder above may be certified meanwhile)."""
    _refuse_inside_certified_now(Path(folder), command)
    recheck_when_marked(folder, lambda: _refuse_inside_certified_now(Path(folder), command))


def _refuse_inside_certified_now(root: Path, command: str) -> None:
    """``refuse_inside_certified``'s check, once."""
    from sensorgap.errors import InputError

    if certified_parent(root, command) is not None:
        return
    above = _certified_above(root)
    if above is not None:
        parent, first = above
        raise InputError(
            "--out",
            "",
            f"{root} lies inside {parent}, a certified folder (its {MANIFEST_NAME} lists "
            f"{first}); {command} would write files there that its {MANIFEST_NAME} does not "
            f"list, so verify {parent} would fail: give another --out (a new folder or one of "
            "your own files, outside it)",
        )


def crowded(folder: str | Path) -> bool:
    """Whether ``folder`` holds more than ``MAX_OUT_ENTRIES`` files and folders (counted
    up to that: cheap for ``/``)."""
    import os

    seen = 0
    for _dirpath, dirnames, filenames in os.walk(folder):
        seen += len(dirnames) + len(filenames)
        if seen > MAX_OUT_ENTRIES:
            return True
    return False


def _first_link(folder: Path) -> str | None:
    """The first entry below ``folder`` (relative path) that is a symbolic link or neither a
    file nor a folder, or None (walked as ``crowded``: call it first to bound the walk)."""
    import os

    for dirpath, dirnames, filenames in os.walk(folder):
        for name in sorted(dirnames) + sorted(filenames):
            path = Path(dirpath) / name
            if path.is_symlink() or not (path.is_dir() or path.is_file()):
                return path.relative_to(folder).as_posix()
    return None


def same_file(a: str | Path, b: str | Path) -> bool:
    """Whether two existing paths name the same file (also under two names); False when
    either cannot be found or read."""
    try:
        return os.path.samefile(a, b)
    except OSError:  # one of them does not exist: not the same file
        return False


def refuse_links(folder: str | Path, what: str, command: str) -> None:
    """Before ``command`` certifies every file of ``folder`` (its manifest lists the whole
    folder): refused (``InputError`` naming ``what``) when an entry below it is a symbolic
    link or neither a file nor a folder (``_first_link``): ``verify`` rejects links and
    never follows them, so the command exited 0 and its own ``verify`` failed. Call it
    after ``crowded`` bounds the walk, and after the command's own checks of the files it
    writes (whose lines say more). A folder that does not exist passes."""
    from sensorgap.errors import InputError

    root = Path(folder)
    if not root.is_dir():
        return
    odd = _first_link(root)
    if odd is not None:
        raise InputError(
            what,
            "",
            f"{root} holds {odd}, a symbolic link or not a regular file: {command} certifies "
            "every file of the folder, and verify rejects links (never following them); "
            "move it away or give another folder",
        )


#: The fewest bytes one file's entry takes in ``manifest.json`` besides its path
#: (``json_bytes``' indented form with a one-digit size and the SHA-256):
#: ``manifest_lower_bound``.
MANIFEST_ENTRY_BYTES = 118


def manifest_lower_bound(folder: str | Path) -> tuple[int, int]:
    """(files, bytes): the files below ``folder`` a manifest would list (up to
    ``MAX_OUT_ENTRIES`` entries walked; not the manifest itself nor temporary-looking
    files) and the fewest bytes a manifest listing them takes (their relative
    paths plus ``MANIFEST_ENTRY_BYTES`` each): over ``MAX_MANIFEST_BYTES`` means no
    manifest ``verify`` can read, known before any work."""
    import os

    root = os.fspath(folder)
    files = size = seen = 0
    for dirpath, dirnames, filenames in os.walk(root):
        seen += len(dirnames) + len(filenames)
        rel_dir = os.path.relpath(dirpath, root)
        base = 0 if rel_dir == "." else len(rel_dir.encode("utf-8", "surrogateescape")) + 1
        for name in filenames:
            if (base == 0 and name == MANIFEST_NAME) or is_temporary(name):
                continue  # never listed
            files += 1
            size += base + len(name.encode("utf-8", "surrogateescape")) + MANIFEST_ENTRY_BYTES
        if seen > MAX_OUT_ENTRIES:
            break
    return files, size


def refuse_crowded_out(folder: str | Path, command: str, what: str = "--out") -> None:
    """The folder ``what`` (an option: ``--out``; ``--run`` of an export in place or a
    report) of ``search``, ``export`` or ``report``, which hash every file of the folder
    into its manifest: an existing folder of more than ``MAX_OUT_ENTRIES`` files and
    folders (a user's home) is refused before any work (``InputError`` naming ``what``;
    hostile round 32: an export in place named --out, which the user had not given)."""
    from sensorgap.errors import InputError

    if not Path(folder).is_dir():
        return
    advice = (
        "move the files that are not the run's out of it"
        if what == "--run"
        else f"give another {what}"
    )
    if crowded(folder):
        raise InputError(
            what,
            "",
            f"{folder} holds more than {MAX_OUT_ENTRIES} files and folders; {command} lists "
            f"and hashes every file of its folder into manifest.json: {advice}",
        )
    files, size = manifest_lower_bound(folder)
    if size > MAX_MANIFEST_BYTES:  # (hostile round 33: refused only after the work)
        raise InputError(
            what,
            "",
            f"{folder}'s manifest.json would take at least {size} bytes ({files} files, "
            f"long paths), and verify reads at most {MAX_MANIFEST_BYTES // 1_000_000} MB: "
            f"{advice}",
        )


def refuse_if_source_changed(folder: str | Path, reads: tuple[str, ...], what: str) -> None:
    """Before a command copies files of a folder with a ``manifest.json`` into another
    folder and certifies them there (``export --run RUN --out CAT`` copies ranking.json,
    run.json and inputs/): every file the manifest lists below ``reads`` (as for
    ``refuse_if_changed``) must be as recorded; a file changed by hand would otherwise be
    certified by the new folder's manifest. ``what`` names the new folder (e.g. "a
    catalog"). Raises ``InputError`` naming the source's manifest and the first such file;
    a folder without a manifest is not checked."""
    root = Path(folder)
    _refuse_unmatched(
        root,
        lambda rel, why: _written_by(rel, reads) and not why.endswith("is not in the manifest"),
        "",
        f"{what} made from it would certify that; restore the file (sensorgap verify "
        f"{root}) or search again",
    )


def _refuse_unmatched(
    root: Path, refused: Callable[[str, str], bool], more_hint: str, advice: str
) -> None:
    """Raise the one-line ``InputError`` of a folder with a ``manifest.json`` that no
    longer matches it: the problems (``_manifest_problems``: relative path, message) that
    ``refused`` picks, the first named; none, or no manifest: return."""
    from sensorgap.errors import InputError

    if not (root / MANIFEST_NAME).is_file():
        return
    bad = [why for rel, why in _manifest_problems(root) if refused(rel, why)]
    if not bad:
        return
    more = f" (and {len(bad) - 1} more{more_hint})" if len(bad) > 1 else ""
    raise InputError(
        root / MANIFEST_NAME,
        "files",
        f"the folder no longer matches its manifest: {bad[0]}{more}; {advice}",
    )


def verify_manifest(folder: str | Path) -> list[str]:
    """Problems of a run folder against its ``manifest.json`` (checked with
    ``read_manifest``): listed files missing, not regular files or changed (size or
    SHA-256); symbolic links anywhere in the folder (never followed); files not listed,
    left-over temporary files and database journals included. Empty when the folder is
    intact. Reads only inside the folder."""
    return [why for _, why in _manifest_problems(Path(folder))]


def _manifest_problems(root: Path) -> list[tuple[str, str]]:
    """``verify_manifest``'s problems as (relative path, message)."""
    listed = read_manifest(root)
    unreadable: dict[str, str] = {}
    entries = dict(_walk(root, unreadable))
    problems: list[tuple[str, str]] = []
    for rel, kind in entries.items():
        if kind == "link":
            problems.append(
                (rel, f"{cut_name(rel)} is a symbolic link (not allowed in a run folder)")
            )
    for rel, meta in sorted(listed.items()):
        found = entries.get(rel)
        if found is None:
            folder = _unreadable_folder(rel, unreadable)
            if folder is None:
                problems.append((rel, f"{cut_name(rel)} is missing"))
            else:
                problems.append(
                    (
                        rel,
                        f"{cut_name(rel)} cannot be read: its folder {folder} cannot be listed "
                        f"({unreadable[folder]})",
                    )
                )
            continue
        if found != "file":
            problems.append((rel, f"{cut_name(rel)} is not a regular file"))
            continue
        if is_temporary(rel.rsplit("/", 1)[-1]) or _in_temporary_folder(rel):
            # never listed by sensorgap (write_manifest leaves such files out, and a command
            # refuses a folder holding one: refuse_uncertifiable): a manifest edited by hand
            problems.append(
                (
                    rel,
                    f"{cut_name(rel)} is named like a temporary or journal file, which no "
                    "manifest written by sensorgap lists",
                )
            )
            continue
        try:
            size = (root / rel).lstat().st_size
            same = meta["bytes"] == size and _sha256_file(root / rel) == (size, meta["sha256"])
        except OSError as exc:
            problems.append((rel, f"{cut_name(rel)} cannot be read ({exc.strerror})"))
            continue
        if not same:
            problems.append((rel, f"{cut_name(rel)} was changed (size or SHA-256 differs)"))
    for folder, why in sorted(unreadable.items()):
        if not any(_unreadable_folder(rel, unreadable) == folder for rel in listed):
            problems.append(
                (folder, f"{folder} cannot be listed ({why}): what it holds cannot be checked")
            )
    restores = [
        rel for rel, kind in entries.items() if kind == "dir" and _is_restore_folder(root / rel)
    ]
    for rel in restores:  # one line each, not one per kept file
        # its kept files, the index aside (-1 when the folder cannot even be listed)
        kept = max(0, sum(1 for r in entries if r.startswith(f"{rel}/")) - 1)
        parent = (root / rel).parent
        if locked_elsewhere(parent):  # a command writing that folder now uses it
            where = parent.relative_to(root).as_posix()
            problems.append(
                (
                    rel,
                    f"{cut_name(rel)} is the restore folder of a sensorgap command writing "
                    f"{where if where != '.' else root} now (its lock is held); "
                    f"{_RESTORE_IN_USE}",
                )
            )
            continue
        problems.append(
            (
                rel,
                f"{cut_name(rel)} is left over from a killed command: it holds "
                f"{f'the {kept} files' if kept else 'the files'} the folder had before that "
                f"command started (its index.json names each number's path); {_RESTORE_BY_HAND}",
            )
        )
    for rel, kind in entries.items():
        if kind in ("dir", "link") or rel == MANIFEST_NAME or rel in listed:
            continue
        if any(rel.startswith(f"{r}/") for r in restores):
            continue
        if is_temporary(rel.rsplit("/", 1)[-1]) or _in_temporary_folder(rel):
            problems.append(
                (
                    rel,
                    f"{cut_name(rel)} is a left-over temporary or journal file (from an "
                    "interrupted command; not in the manifest)",
                )
            )
        else:
            problems.append((rel, f"{cut_name(rel)} is not in the manifest"))
    return problems


def path_argument(value: object, name: str) -> Path:
    """A path argument of the library: a non-empty ``str`` or ``os.PathLike`` without a
    NUL character (``Path("")`` would be the working directory; a NUL was a raw
    ``ValueError`` of the OS layer), else ``InputError`` naming ``name``."""
    from sensorgap.errors import InputError

    try:
        shown = repr(value)[:80]
    except ValueError:  # an int too long for repr
        shown = f"an {type(value).__name__} of more digits than repr shows"
    if isinstance(value, os.PathLike):
        value = os.fspath(value)
    if not isinstance(value, str) or not value.strip():
        raise InputError(name, "", f"must be a path (a non-empty str or Path), got {shown}")
    if "\x00" in value:
        raise InputError(name, "", f"must not hold a NUL character, got {shown}")
    return Path(value)


def refuse_file_on_the_way(folder: Path, name: str) -> None:
    """An output folder ``folder`` whose nearest existing part is not a folder (a file
    there, or on the way to it) is refused (``InputError`` naming ``name``): it was a raw
    ``FileExistsError`` or ``NotADirectoryError`` once the work had started."""
    from sensorgap.errors import InputError

    probe = folder
    try:
        while not os.path.lexists(probe) and probe != probe.parent:
            probe = probe.parent
        if os.path.lexists(probe) and not probe.is_dir():
            raise InputError(name, "", f"{probe} is a file, not a folder")
    except OSError as exc:
        raise InputError(name, "", f"{folder}: cannot be read ({exc.strerror})") from None
