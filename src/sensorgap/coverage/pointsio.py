"""Reading query points (``x,y[,z]`` CSV, vehicle frame, m)."""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sensorgap.config.common import MAX_NUMBER_CHARS, parse_decimal
from sensorgap.errors import InputError

#: Input limits (docs/limits.md): points per file, file size, and points x sensors (the
#: per-sensor columns of ``probe``: ~3.3 kB per point of System A's 23 sensors, measured by
#: benchmarks/bench_limits.py, so <= ~2 GiB at the limit).
MAX_POINTS = 500_000
MAX_BYTES = 100_000_000
MAX_POINT_SENSOR_VALUES = 12_000_000
#: A target body (``probe --heading``) costs this many points' worth of memory.
BODY_COST = 12
#: Largest coordinate of a query point, m, either way.
MAX_POINT_COORD_M = 1.0e7  # written "1e7" in the error lines
#: Longest CSV field accepted, characters (a number needs far fewer): the longest number
#: text read anywhere (``config.common.MAX_NUMBER_CHARS``).
MAX_FIELD_CHARS = MAX_NUMBER_CHARS
#: Highest target point above the road plane, m (``probe`` z, ``coverage --height``): an
#: estimate well above any road user (a truck is 4 m) and any sensor mount; the models know
#: no terrain, so a point below the road (z < 0) is refused too.
MAX_HEIGHT_M = 50.0


def check_point_count(
    points: int, sensors: int, source: str | Path, bodies: str | None = None, remedy: str = ""
) -> None:
    """At most ``MAX_POINTS`` query points, and at most ``MAX_POINT_SENSOR_VALUES`` points x
    sensors (a target body counts ``BODY_COST`` points; ``bodies``: how the error says
    they are bodies, e.g. `` with --heading``, None for points), else ``InputError``
    naming ``source`` (with ``remedy`` after the limit)."""
    tail = f"; {remedy}" if remedy else ""
    if points > MAX_POINTS:
        raise InputError(source, "", f"{points} points; at most {MAX_POINTS} allowed{tail}")
    per_point = sensors * (1 if bodies is None else BODY_COST)
    if points * per_point > MAX_POINT_SENSOR_VALUES:
        raise InputError(
            source,
            "",
            f"{points} points x {sensors} sensors "
            f"is too many (at most {MAX_POINT_SENSOR_VALUES // per_point} points "
            f"for this vehicle{bodies or ''}){tail}",
        )


def read_points_csv(path: Path, default_z: float, heights: bool = True) -> NDArray[np.float64]:
    """(N, 3) points from a CSV with a header naming ``x`` and ``y`` (m, vehicle frame) and
    optionally ``z`` (m above the road plane, within 0..``MAX_HEIGHT_M``; else
    ``default_z``). Other columns are ignored. Without ``heights`` (target bodies, which
    stand on the road) a ``z`` column is refused rather than dropped. Any bad cell ->
    ``InputError``."""
    if not path.exists():
        raise InputError(path, "", "file not found")
    if not path.is_file():  # a folder, a device (/dev/zero) or a pipe: never read
        raise InputError(path, "", "not a regular file (a folder, device or pipe)")
    if path.stat().st_size > MAX_BYTES:
        raise InputError(path, "", f"larger than {MAX_BYTES} bytes")
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (UnicodeDecodeError, OSError) as exc:
        raise InputError(path, "", f"cannot read as UTF-8 text ({exc})") from None
    reader = csv.reader(io.StringIO(text))
    try:
        header = next(reader, None)
    except csv.Error as exc:
        raise InputError(path, "header", f"not CSV: {exc}") from None
    if not header:
        raise InputError(path, "header", "empty file; expected a header 'x,y' or 'x,y,z'")
    names = [h.strip().lower() for h in header]
    seen: set[str] = set()
    for n in names:
        if n and n in seen:  # which of the two would be read is not the user's choice
            raise InputError(
                path, "header", f"column {n[:40]!r} appears twice; expected one each of x,y[,z]"
            )
        seen.add(n)
    for col in ("x", "y"):
        if col not in names:
            raise InputError(
                path,
                "header",
                f"missing column {col!r}; expected x,y[,z], got {','.join(header)!r}",
            )
    ix, iy = names.index("x"), names.index("y")
    iz = names.index("z") if "z" in names else None
    if iz is not None and not heights:
        raise InputError(
            path,
            "header",
            "a z column is not used for target bodies (a body stands on the road); "
            "remove it, or probe points without a heading",
        )
    rows: list[tuple[float, float, float]] = []
    try:
        return _rows(path, reader, (ix, iy, iz, len(header)), default_z, rows)
    except csv.Error as exc:
        raise InputError(
            path,
            f"line {reader.line_num}",
            f"not CSV ({exc}); fields are numbers of at most {MAX_FIELD_CHARS} characters",
        ) from None


def _rows(
    path: Path,
    reader: Any,
    columns: tuple[int, int, int | None, int],
    default_z: float,
    rows: list[tuple[float, float, float]],
) -> NDArray[np.float64]:
    ix, iy, iz, width = columns
    last = reader.line_num  # the header's last line
    for row in reader:
        # the row's first line in the file (a quoted field may hold line breaks, so rows
        # and lines differ: hostile round 27 was told line 3 for a value on line 5)
        lineno, last = last + 1, reader.line_num
        if not row or all(not c.strip() for c in row):
            continue
        if len(row) != width:  # a shifted row: its x, y, z would be other columns
            raise InputError(
                path,
                f"line {lineno}",
                f"{len(row)} fields, but the header names {width} columns",
            )
        if len(rows) >= MAX_POINTS:
            raise InputError(path, "", f"more than {MAX_POINTS} points")
        vals = []
        for name, idx in (("x", ix), ("y", iy), ("z", iz)):
            if idx is None:
                vals.append(default_z)
                continue
            cell = row[idx].strip() if idx < len(row) else ""
            if len(cell) > MAX_FIELD_CHARS:
                raise InputError(
                    path,
                    f"line {lineno}, column {name}",
                    f"field of {len(cell)} characters; at most {MAX_FIELD_CHARS} allowed",
                )
            try:
                v = parse_decimal(cell)
            except ValueError:
                v = math.nan
            if not math.isfinite(v) or abs(v) > MAX_POINT_COORD_M:
                raise InputError(
                    path,
                    f"line {lineno}, column {name}",
                    f"expected a finite number within +-1e7 m, got {cell!r}",
                )
            if name == "z" and not 0.0 <= v <= MAX_HEIGHT_M:
                raise InputError(
                    path,
                    f"line {lineno}, column z",
                    f"must be within 0..{MAX_HEIGHT_M:g} m (above the road plane the vehicle "
                    f"stands on: the models know no terrain), got {cell!r}",
                )
            vals.append(v)
        rows.append((vals[0], vals[1], vals[2]))
    if not rows:
        raise InputError(path, "", "no data rows")
    return np.array(rows, dtype=np.float64)
