"""``sensorgap compare`` refuses a missing run. The A-vs-B tests (the top lists differ and
every difference is traced to the sensor setups) use the report tests' shared comparison:
tests/report/test_compare_ab.py."""

from __future__ import annotations

from pathlib import Path

import pytest

from sensorgap.cli import main


def test_missing_run_is_one_line_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert (
        main(["compare", str(tmp_path / "nope"), str(tmp_path), "--out", str(tmp_path / "o")]) == 2
    )
    err = capsys.readouterr().err.strip()
    assert "ranking.json is missing" in err and len(err.splitlines()) == 1
