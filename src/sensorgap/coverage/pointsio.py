"""Reading query points (``x,y[,z]`` CSV, vehicle frame, m)."""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from sensorgap.errors import InputError

MAX_POINTS = 10_000_000
MAX_BYTES = 1_000_000_000


def read_points_csv(path: Path, default_z: float) -> NDArray[np.float64]:
    """(N, 3) points from a CSV with a header naming ``x`` and ``y`` (and optionally ``z``,
    else ``default_z`` m). Other columns are ignored. Any bad cell -> ``InputError``."""
    if not path.is_file():
        raise InputError(path, "", "file not found")
    if path.stat().st_size > MAX_BYTES:
        raise InputError(path, "", f"larger than {MAX_BYTES} bytes")
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (UnicodeDecodeError, OSError) as exc:
        raise InputError(path, "", f"cannot read as UTF-8 text ({exc})") from None
    reader = csv.reader(io.StringIO(text))
    header = next(reader, None)
    if not header:
        raise InputError(path, "header", "empty file; expected a header 'x,y' or 'x,y,z'")
    names = [h.strip().lower() for h in header]
    for col in ("x", "y"):
        if col not in names:
            raise InputError(path, "header", f"missing column {col!r}; expected x,y[,z], "
                             f"got {','.join(header)!r}")
    ix, iy = names.index("x"), names.index("y")
    iz = names.index("z") if "z" in names else None
    rows: list[tuple[float, float, float]] = []
    for lineno, row in enumerate(reader, start=2):
        if not row or all(not c.strip() for c in row):
            continue
        if len(rows) >= MAX_POINTS:
            raise InputError(path, "", f"more than {MAX_POINTS} points")
        vals = []
        for name, idx in (("x", ix), ("y", iy), ("z", iz)):
            if idx is None:
                vals.append(default_z)
                continue
            cell = row[idx].strip() if idx < len(row) else ""
            try:
                v = float(cell)
            except ValueError:
                v = math.nan
            if not math.isfinite(v) or abs(v) > 1.0e7:
                raise InputError(path, f"line {lineno}, column {name}",
                                 f"expected a finite number within +-1e7 m, got {cell!r}")
            vals.append(v)
        rows.append((vals[0], vals[1], vals[2]))
    if not rows:
        raise InputError(path, "", "no data rows")
    return np.array(rows, dtype=np.float64)
