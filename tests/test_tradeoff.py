"""``sensorgap tradeoff --quick``: the table, the plot, the measured errors behave."""

from __future__ import annotations

import csv
from pathlib import Path

from sensorgap.cli import main


def test_tradeoff_quick(tmp_path: Path) -> None:
    assert main(["tradeoff", "--out", str(tmp_path), "--quick"]) == 0
    for name in ("tradeoff.csv", "tradeoff.md", "resolution.png", "manifest.json"):
        assert (tmp_path / name).is_file()
    rows = list(csv.DictReader((tmp_path / "tradeoff.csv").open()))
    res = [r for r in rows if r["study"] == "grid resolution"]
    assert [r["setting"] for r in res] == ["0.5 m", "0.2 m", "0.1 m"]
    errs = [float(r["error"]) for r in res]
    assert errs[-1] < errs[0]  # a finer grid is closer to the exact polygons
    mean_dpd = [float(r["path_mean_abs_dpd"]) for r in res]
    assert mean_dpd[-1] < mean_dpd[0]
    scoped = [r for r in rows if r["setting"] == "exact, scene-limited (bodies)"]
    assert scoped and all(float(r["error"]) == 0.0 for r in scoped)
    lookup = [r for r in rows if r["setting"] == "lookup (bodies)"]
    assert lookup and all(float(r["mean_error"]) < 0.05 for r in lookup)
    points = [r for r in rows if r["setting"].startswith("exact, points")]
    assert points and all(float(r["time_s"]) > 0 for r in points)
