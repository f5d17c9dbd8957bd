"""``sensorgap tradeoff --quick``: the table, the plot, the measured errors behave."""

from __future__ import annotations

import csv
from pathlib import Path

from sensorgap.cli import main


def test_tradeoff_quick(tmp_path: Path) -> None:
    assert main(["tradeoff", "--out", str(tmp_path), "--quick"]) == 0
    for name in ("tradeoff.csv", "tradeoff.md", "resolution.png", "manifest.json"):
        assert (tmp_path / name).is_file()
    rows = list(
        csv.DictReader(
            (tmp_path / "tradeoff.csv").read_text(encoding="utf-8").splitlines(keepends=True)
        )
    )
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


#: The columns of tradeoff.csv that are measured times of the run (they differ between runs)
TIME_COLUMNS = ("time_s", "ms_per_candidate", "path_grid_time_s", "path_exact_time_s")


def test_tradeoff_accuracy_columns_are_reproducible(tmp_path: Path) -> None:
    """Two runs agree on every column but the measured times (and the figure that plots
    them): the accuracy side of the trade-off is an exact computation, not a sample."""
    tables = []
    for name in ("a", "b"):
        assert main(["tradeoff", "--out", str(tmp_path / name), "--quick"]) == 0
        rows = list(
            csv.DictReader(
                (tmp_path / name / "tradeoff.csv")
                .read_text(encoding="utf-8")
                .splitlines(keepends=True)
            )
        )
        tables.append([{k: v for k, v in r.items() if k not in TIME_COLUMNS} for r in rows])
    assert tables[0] == tables[1] and len(tables[0]) >= 10
    assert set(TIME_COLUMNS) <= set(
        csv.DictReader(
            (tmp_path / "a" / "tradeoff.csv").read_text(encoding="utf-8").splitlines(keepends=True)
        ).fieldnames
        or ()
    )
