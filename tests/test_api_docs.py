"""docs/api.md: every ``python`` block runs, in order, in a temporary folder."""

from __future__ import annotations

import os
import re
from pathlib import Path

DOC = Path(__file__).resolve().parents[1] / "docs" / "api.md"


def test_api_examples_run(tmp_path: Path, capsys) -> None:
    blocks = re.findall(r"```python\n(.*?)```", DOC.read_text(encoding="utf-8"), re.S)
    assert len(blocks) >= 2
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        namespace: dict[str, object] = {}
        for code in blocks:
            exec(compile(code, str(DOC), "exec"), namespace)  # noqa: S102
    finally:
        os.chdir(cwd)
    out = capsys.readouterr().out
    assert "ranked;" in out and "scenarios;" in out
    assert (tmp_path / "run_b" / "report.html").is_file()


def test_root_names_are_the_facade_names() -> None:
    """The root package lists the facade's names (``_API``) without importing
    ``sensorgap.api`` (so ``import sensorgap`` stays light): the same names, in the same
    order, as ``sensorgap.api.__all__``, each one resolving to the facade's object."""
    import sensorgap
    from sensorgap import api

    assert tuple(api.__all__) == sensorgap._API
    assert all(getattr(sensorgap, n) is getattr(api, n) for n in sensorgap._API)
