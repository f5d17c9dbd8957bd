"""Shared fixtures: the shipped presets, scenes and a hardened numpy error state; the
grouping of tests for parallel workers (pytest-xdist, ``make test``)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from sensorgap.config import load_environment, load_target
from sensorgap.coverage import Scene
from sensorgap.models import Conditions, System, load_system

TESTS = Path(__file__).resolve().parent
#: Folders whose files share costly session-scoped fixtures (a conftest.py beside them):
#: their tests run on one worker, so each fixture is built once per session.
SHARED_FIXTURE_DIRS = ("export", "report")


def xdist_group_of(path: Path) -> str:
    """The parallel-worker group of a test file: its folder when that folder shares
    session fixtures (``SHARED_FIXTURE_DIRS``), else the file itself."""
    rel = path.resolve().relative_to(TESTS)
    if rel.parts[0] in SHARED_FIXTURE_DIRS:
        return rel.parts[0]
    return rel.as_posix()


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Under ``pytest -n N --dist loadgroup`` (``make test``), the tests of one file (or of
    one fixture-sharing folder) go to one worker: module- and session-scoped fixtures are
    built once, not once per worker. Without xdist the mark is unused."""
    for item in items:
        if item.get_closest_marker("xdist_group") is None:
            item.add_marker(pytest.mark.xdist_group(xdist_group_of(item.path)))


@pytest.fixture(autouse=True)
def _numpy_raises() -> Iterator[None]:
    """Every floating-point error (overflow, invalid, divide) fails the test."""
    with np.errstate(all="raise", under="ignore"):
        yield


@pytest.fixture(scope="session")
def system_a() -> System:
    return load_system("system_a")


@pytest.fixture(scope="session")
def system_b() -> System:
    return load_system("system_b")


def make_scene(system: System, target: str = "car", env: str = "clear",
               heading: float = 0.0) -> Scene:
    """A scene from preset names."""
    return Scene(system, load_target(target),
                 Conditions.from_config(load_environment(env), heading))
