"""Speed vs accuracy (issue #7): ``sensorgap tradeoff`` run from the benchmarks; prints its
table. ``python benchmarks/run.py tradeoff``."""

from __future__ import annotations

import tempfile
from pathlib import Path

from sensorgap.tradeoff import run_tradeoff


def run() -> str:
    """Run the trade-off study in a temporary folder; returns its Markdown table."""
    with tempfile.TemporaryDirectory() as tmp:
        run_tradeoff(Path(tmp))
        return (Path(tmp) / "tradeoff.md").read_text()


if __name__ == "__main__":
    print(run())
