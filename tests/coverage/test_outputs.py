"""Reading a coverage map back (``coverage.outputs.read_coverage_npz``): what a report
trusts of a map in a run folder is checked, one line naming the file and the field."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sensorgap.coverage.outputs import read_coverage_npz
from sensorgap.errors import InputError


def _npz(path: Path, x: list[float], y: list[float], res: float) -> Path:
    pd = np.full((len(y), len(x)), 0.5)
    np.savez(path, pd=pd, x=np.array(x), y=np.array(y), resolution=np.array([res]))
    return path


def test_a_map_as_written_reads_back(tmp_path: Path) -> None:
    pd, x, y, res = read_coverage_npz(_npz(tmp_path / "m.npz", [0.5, 1.5, 2.5], [0.5, 1.5], 1.0))
    assert pd.shape == (2, 3) and res == 1.0 and x.tolist() == [0.5, 1.5, 2.5]


@pytest.mark.parametrize(
    ("x", "res", "field", "says"),
    [
        # hostile round sixteen: a cell of 1e300 m passed "finite and > 0" and overflowed
        # the report's blind-spot extents (internal error)
        ([0.5], 1e300, "resolution", "at most 200000 m"),
        # a map whose cells are 2 m apart but which says 1 m (its areas would be a quarter)
        ([0.5, 2.5, 4.5], 1.0, "x", "the resolution (1 m) apart"),
    ],
)
def test_a_map_whose_cell_size_cannot_be_true_is_refused(
    tmp_path: Path, x: list[float], res: float, field: str, says: str
) -> None:
    path = _npz(tmp_path / "m.npz", x, [0.5], res)
    with pytest.raises(InputError) as err:
        read_coverage_npz(path)
    assert err.value.field == field and says in err.value.message
