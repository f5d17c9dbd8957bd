"""Deterministic, atomic writers for the file formats sensorgap emits (CSV, JSON, NPZ).

Same inputs -> byte-identical files: fixed float formatting, sorted JSON keys, zip entries
with a fixed timestamp. Every writer goes through ``sensorgap.atomic``.
"""

from __future__ import annotations

import io
import json
import math
import zipfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sensorgap.atomic import atomic_write_bytes

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
    lines = [",".join(columns)]
    cols = [np.asarray(c) for c in data]
    n = len(cols[0]) if cols else 0
    fmt = [
        (format_float if c.dtype.kind == "f" else str) for c in cols
    ]
    lists = [c.tolist() for c in cols]
    for i in range(n):
        lines.append(",".join(f(col[i]) for f, col in zip(fmt, lists, strict=True)))
    return ("\n".join(lines) + "\n").encode("utf-8")


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
    return (text + "\n").encode("utf-8")


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
_MANIFEST_SKIP_SUFFIXES = (".tmp", "-journal", "-wal", "-shm")


def write_manifest(folder: str | Path) -> Path:
    """Write ``folder/manifest.json``: every file below ``folder`` (sorted relative POSIX
    paths) with its size in bytes and SHA-256, so an assessor can verify that nothing was
    changed or lost. Deterministic: no timestamps. Temporary and database journal files are
    left out, and so is the manifest itself."""
    import hashlib

    root = Path(folder)
    files = {}
    for p in sorted(root.rglob("*")):
        if not p.is_file() or p.name == MANIFEST_NAME or p.name.endswith(_MANIFEST_SKIP_SUFFIXES):
            continue
        if p.name.startswith(".") and ".tmp" in p.name:
            continue
        data = p.read_bytes()
        files[p.relative_to(root).as_posix()] = {
            "bytes": len(data), "sha256": hashlib.sha256(data).hexdigest()}
    return write_json(root / MANIFEST_NAME, {"algorithm": "sha256", "files": files})


def verify_manifest(folder: str | Path) -> list[str]:
    """Problems of a run folder against its ``manifest.json``: files missing, changed (size
    or SHA-256) or not listed. Empty when the folder is intact."""
    import hashlib

    root = Path(folder)
    data = json.loads((root / MANIFEST_NAME).read_text(encoding="utf-8"))
    listed = data["files"]
    problems = []
    for rel, meta in sorted(listed.items()):
        p = root / rel
        if not p.is_file():
            problems.append(f"{rel} is missing")
            continue
        raw = p.read_bytes()
        if len(raw) != meta["bytes"] or hashlib.sha256(raw).hexdigest() != meta["sha256"]:
            problems.append(f"{rel} was changed (size or SHA-256 differs)")
    for p in sorted(root.rglob("*")):
        rel = p.relative_to(root).as_posix()
        if (p.is_file() and p.name != MANIFEST_NAME and rel not in listed
                and not p.name.endswith(_MANIFEST_SKIP_SUFFIXES)
                and not (p.name.startswith(".") and ".tmp" in p.name)):
            problems.append(f"{rel} is not in the manifest")
    return problems
