"""Every evaluated candidate in an SQLite file (stdlib ``sqlite3``); resume from it.

Table ``candidates``: one row per evaluation, keyed by (family, idx) where ``idx`` counts
the family's evaluations in the strategy's order; parameters and metrics as sorted JSON,
risk and feasibility as columns for SQL queries. Table ``meta`` holds the run settings.
Each batch is committed at once, so an interrupted run loses at most one batch; rerunning
the same command replays the (deterministic) strategy and takes every stored result
instead of evaluating it again.
"""

from __future__ import annotations

import json
import sqlite3
from pathlib import Path
from typing import Any

from sensorgap.errors import InputError
from sensorgap.search.problem import Candidate, Result

SCHEMA = """
CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS candidates (
    family TEXT NOT NULL,
    idx INTEGER NOT NULL,
    scenario_id TEXT NOT NULL,
    environment TEXT NOT NULL,
    sun_azimuth_deg REAL,
    sun_elevation_deg REAL,
    params TEXT NOT NULL,
    metrics TEXT NOT NULL,
    risk REAL NOT NULL,
    feasible INTEGER NOT NULL,
    note TEXT NOT NULL,
    PRIMARY KEY (family, idx)
);
"""


class Store:
    """The run's SQLite file."""

    def __init__(self, path: Path, settings: dict[str, Any]) -> None:
        self.path = path
        path.parent.mkdir(parents=True, exist_ok=True)
        self.db = sqlite3.connect(path)
        self.db.executescript(SCHEMA)
        text = json.dumps(settings, sort_keys=True)
        row = self.db.execute("SELECT value FROM meta WHERE key = 'settings'").fetchone()
        if row is None:
            self.db.execute("INSERT INTO meta VALUES ('settings', ?)", (text,))
            self.db.commit()
        elif row[0] != text:
            self.db.close()
            raise InputError("--out", "", f"{path} holds a search with different settings; "
                             "use another --out folder (or delete it) to start a new search")

    def close(self) -> None:
        """Close the connection."""
        self.db.close()

    def count(self) -> int:
        """Number of stored evaluations."""
        return int(self.db.execute("SELECT COUNT(*) FROM candidates").fetchone()[0])

    def get(self, family: str, idx: int, scenario_id: str) -> Result | None:
        """The stored result of evaluation ``idx`` of ``family`` if it is that candidate."""
        row = self.db.execute(
            "SELECT scenario_id, environment, sun_azimuth_deg, sun_elevation_deg, params, "
            "metrics, feasible, note FROM candidates WHERE family = ? AND idx = ?",
            (family, idx)).fetchone()
        if row is None or row[0] != scenario_id:
            return None
        sun = None if row[2] is None else (float(row[2]), float(row[3]))
        cand = Candidate(family, row[1], sun, json.loads(row[4]))
        return Result(cand, json.loads(row[5]), bool(row[6]), row[7])

    def put(self, rows: list[tuple[int, Result]]) -> None:
        """Insert (or replace) results and commit."""
        data = []
        for idx, r in rows:
            c = r.candidate
            data.append((c.family, idx, c.scenario_id, c.environment,
                         None if c.sun is None else c.sun[0],
                         None if c.sun is None else c.sun[1],
                         json.dumps(c.params, sort_keys=True),
                         json.dumps(r.metrics, sort_keys=True), r.risk, int(r.feasible),
                         r.note))
        self.db.executemany("INSERT OR REPLACE INTO candidates VALUES "
                            "(?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)", data)
        self.db.commit()

    def all_results(self) -> list[Result]:
        """Every stored result (family, idx order)."""
        out = []
        for fam, idx in self.db.execute(
                "SELECT family, idx FROM candidates ORDER BY family, idx").fetchall():
            sid = self.db.execute("SELECT scenario_id FROM candidates WHERE family = ? AND "
                                  "idx = ?", (fam, idx)).fetchone()[0]
            r = self.get(fam, idx, sid)
            if r is not None:
                out.append(r)
        return out
