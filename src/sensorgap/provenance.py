"""Provenance of a run: software versions, config hashes, the command (``run.json``).

``run.json`` is deterministic (no timestamp): the one timestamp of a run is the report's
generation time (``utc_now``; ``SOURCE_DATE_EPOCH`` fixes it, the reproducible-builds
convention).
"""

from __future__ import annotations

import datetime as dt
import hashlib
import os
import platform
from collections.abc import Iterable
from importlib import metadata
from pathlib import Path
from typing import Any

from sensorgap.errors import InputError
from sensorgap.filesio import previous_json_object, write_json

#: Latest ``SOURCE_DATE_EPOCH`` accepted, seconds: 9999-12-31T23:59:59Z (the last second
#: an ISO 8601 date of four digits, and Python's ``datetime``, can hold).
MAX_SOURCE_DATE_EPOCH = 253_402_300_799
#: Longest ``SOURCE_DATE_EPOCH`` accepted, characters (leading zeros count: ``int`` refuses
#: a string of more than 4,300 digits).
MAX_SOURCE_DATE_EPOCH_CHARS = 20

#: Distributions whose versions a run records.
PACKAGES = (
    "sensorgap",
    "numpy",
    "scipy",
    "pandas",
    "numba",
    "pydantic",
    "lxml",
    "networkx",
    "scenariogeneration",
    "xmlschema",
    "shapely",
    "matplotlib",
    "tqdm",
)


def versions() -> dict[str, str]:
    """Python and the installed versions of ``PACKAGES``."""
    out = {"python": platform.python_version()}
    for name in PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out


def sha256_of(path: Path) -> str:
    """SHA-256 (hex) of a file's bytes, read in blocks: memory stays small whatever the
    file's size (a 5 GB file listed in a catalog was read whole to check it: hostile round
    nineteen, F3)."""
    with open(path, "rb") as f:
        return hashlib.file_digest(f, "sha256").hexdigest()


def config_hashes(paths: Iterable[Path], root: Path | None = None) -> dict[str, str]:
    """SHA-256 per config file, keyed by its path relative to ``root`` (or its name)."""
    out = {}
    for p in sorted(set(Path(x) for x in paths)):
        key = p.name
        if root is not None:
            try:
                key = p.resolve().relative_to(root.resolve()).as_posix()
            except ValueError:
                key = p.name
        out[key] = sha256_of(p)
    return out


def source_date_epoch() -> int | None:
    """``SOURCE_DATE_EPOCH`` (the reproducible-builds convention: seconds since
    1970-01-01T00:00:00Z) as an integer, None when it is not set. Only ASCII digits
    within 0 .. ``MAX_SOURCE_DATE_EPOCH`` are accepted: anything else (empty, a sign,
    spaces, '²' or full-width digits, which ``str.isdigit`` takes; a value past the year
    9999, which overflowed; more than ``MAX_SOURCE_DATE_EPOCH_CHARS`` characters, leading
    zeros included, which ``int`` refuses past 4,300 digits) raises ``InputError`` naming
    the variable. numpy's f2py reads
    the variable too when numba imports it (``int(...)``, ``time.gmtime``): the CLI checks
    it before any command starts (``cli.main``)."""
    text = os.environ.get("SOURCE_DATE_EPOCH")
    if text is None:
        return None
    digits = text.isascii() and text.isdigit()
    if not digits or len(text) > MAX_SOURCE_DATE_EPOCH_CHARS or int(text) > MAX_SOURCE_DATE_EPOCH:
        raise InputError(
            "SOURCE_DATE_EPOCH",
            "",
            "must be whole seconds since 1970-01-01T00:00:00Z in ASCII digits, 0 .. "
            f"{MAX_SOURCE_DATE_EPOCH} (9999-12-31T23:59:59Z), or not set; got {text!r}",
        )
    return int(text)


def utc_now() -> str:
    """The run's timestamp (ISO 8601, UTC; ``SOURCE_DATE_EPOCH`` when set, checked by
    ``source_date_epoch``)."""
    epoch = source_date_epoch()
    t = dt.datetime.now(dt.UTC) if epoch is None else dt.datetime.fromtimestamp(epoch, dt.UTC)
    return t.replace(microsecond=0).isoformat().replace("+00:00", "Z")


def write_run_info(
    folder: Path,
    command: list[str],
    vehicle: str,
    files: Iterable[Path],
    settings: dict[str, Any],
    extra: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """``folder/run.json``: command, vehicle, versions, config hashes, settings (+ extra).
    The ``inputs`` a search recorded in an existing ``run.json`` (``search.runfolder``) are
    kept."""
    info: dict[str, Any] = {
        "command": command,
        "vehicle": vehicle,
        "versions": versions(),
        "config_sha256": config_hashes(files, Path.cwd()),
        "settings": settings,
        "platform": f"{platform.system()} {platform.machine()}",
    }
    info.update(extra or {})
    if "inputs" not in info:
        prev = previous_json_object(Path(folder) / "run.json")  # {} when absent or damaged
        if isinstance(prev.get("inputs"), dict):
            info["inputs"] = prev["inputs"]
    write_json(Path(folder) / "run.json", info)
    return info
