"""The search store's background writer (``Store.put_async``): every queued batch is in the
file after ``close``, in order, and a failed write is raised, not lost."""

from __future__ import annotations

from pathlib import Path

import pytest

from sensorgap.search.metrics import metric_names
from sensorgap.search.problem import OBJECTIVE_KEY, Candidate, Result
from sensorgap.search.store import Store

SETTINGS = {"vehicle": "v", "seed": 1}


def _result(i: int, metric: object = 0.5) -> Result:
    metrics = {name: 0.0 for name in [*metric_names(), OBJECTIVE_KEY]}
    metrics["collision_probability"] = metric  # type: ignore[assignment]
    return Result(Candidate("fam", "clear", None, {"x": float(i)}), metrics, True, "")


def test_queued_batches_are_written_in_order(tmp_path: Path) -> None:
    db = tmp_path / "s.sqlite"
    store = Store(db, SETTINGS)
    for b in range(20):
        store.put_async([(b * 10 + j, _result(b * 10 + j)) for j in range(10)])
    store.close()
    again = Store(db, SETTINGS)
    rows = again.all_results()
    again.close()
    assert len(rows) == 200
    assert [r.candidate.params["x"] for r in rows] == sorted(float(i) for i in range(200))


def test_a_failed_background_write_is_raised(tmp_path: Path) -> None:
    store = Store(tmp_path / "s.sqlite", SETTINGS)
    store.put_async([(0, _result(0, metric=object()))])  # not JSON: the write fails
    with pytest.raises(TypeError):
        store.close()
