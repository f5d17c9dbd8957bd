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


def test_a_store_in_wal_mode_is_refused_unopened(tmp_path: Path) -> None:
    """Round 12 (folders): SQLite creates ``-wal`` and ``-shm`` beside a WAL database as
    soon as it opens it, read-only too; sensorgap's store never uses WAL, so such a file
    is refused from its header, by ``Store``, ``check_store`` and ``read_meta`` alike,
    and nothing appears beside it."""
    import sqlite3

    from sensorgap.errors import InputError
    from sensorgap.search.store import check_store, read_meta

    db = tmp_path / "search.sqlite"
    store = Store(db, SETTINGS)
    store.put([(0, _result(0))])
    store.close()
    con = sqlite3.connect(db)
    con.execute("PRAGMA journal_mode=wal")
    con.close()
    before = sorted(p.name for p in tmp_path.iterdir())
    assert before == ["search.sqlite"]
    for opener in (
        lambda: Store(db, SETTINGS),
        lambda: check_store(db, SETTINGS, {}),
        lambda: read_meta(db),
    ):
        with pytest.raises(InputError, match="in WAL mode"):
            opener()
        assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_removing_stale_outputs_removes_the_folders_they_leave_empty(tmp_path: Path) -> None:
    """Round 12 (folders): a resumed search that changed the ranking removed the export's
    maps (``coverage/*``) and left an empty ``coverage/``; a folder that still holds
    other files (an analysis' maps below it), or held nothing removed, stays."""
    from sensorgap.filesio import remove_outputs

    (tmp_path / "coverage").mkdir()
    (tmp_path / "coverage" / "car_clear.png").write_text("map")
    (tmp_path / "scenarios").mkdir()
    (tmp_path / "scenarios" / "a.xosc").write_text("x")
    (tmp_path / "mine").mkdir()  # a user's empty folder, not below a pattern
    gone = remove_outputs(tmp_path, ("coverage/*", "scenarios/"))
    assert gone == ["coverage/car_clear.png", "scenarios/a.xosc"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine"]
    (tmp_path / "coverage" / "car_clear").mkdir(parents=True)
    (tmp_path / "coverage" / "car_clear" / "coverage.npz").write_text("analysis")
    (tmp_path / "coverage" / "car_fog.png").write_text("map")
    assert remove_outputs(tmp_path, ("coverage/*",)) == ["coverage/car_fog.png"]
    assert (tmp_path / "coverage" / "car_clear" / "coverage.npz").is_file()


def test_non_finite_metrics_are_stored_as_standard_json(tmp_path: Path) -> None:
    """Hostile round fifteen noted ``NaN`` in search.sqlite's metrics JSON (not standard
    JSON; other readers refuse it), round eighteen the texts "nan" / "inf" that replaced
    it: an undefined metric (NaN) and a time never reached (inf) are stored as ``null``
    (the output files' empty cell) and read back as NaN; the exact results of the ranked
    rows (``record_ranked``) likewise. Older stores' texts still read as the floats."""
    import json
    import math
    import re
    import sqlite3

    from sensorgap.search.store import (
        RANKED_KEY,
        metrics_from_json,
        read_meta,
        read_results,
        record_ranked,
    )

    db = tmp_path / "s.sqlite"
    r = _result(0)
    r.metrics["t_detect_s"] = math.nan
    r.metrics["t_threat_s"] = math.inf
    r.metrics["detection_margin_s"] = -math.inf
    store = Store(db, SETTINGS)
    store.put([(0, r)])
    store.close()
    record_ranked(db, {r.candidate.scenario_id: dict(r.metrics)})
    con = sqlite3.connect(db)
    texts = [t for (t,) in con.execute("SELECT metrics FROM candidates")]
    texts += [t for (t,) in con.execute("SELECT value FROM meta WHERE key = ?", (RANKED_KEY,))]
    con.close()
    for t in texts:
        assert not re.search(r"(?i)nan|inf", t), t
        json.loads(t, parse_constant=lambda c: pytest.fail(f"non-standard JSON {c}"))
    stored = json.loads(texts[0])
    assert stored["t_detect_s"] is None and stored["t_threat_s"] is None
    assert stored["detection_margin_s"] is None
    for got in (
        read_results(db, [r.candidate.scenario_id])[r.candidate.scenario_id],
        read_meta(db)[RANKED_KEY][r.candidate.scenario_id],
    ):
        assert math.isnan(got["t_detect_s"]) and math.isnan(got["t_threat_s"])
        assert math.isnan(got["detection_margin_s"])
        assert got["collision_probability"] == 0.5
    old = metrics_from_json({"a": "nan", "b": "inf", "c": "-inf", "d": 1.5})
    assert math.isnan(old["a"]) and old["b"] == math.inf and old["c"] == -math.inf
    assert old["d"] == 1.5
