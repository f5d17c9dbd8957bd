"""Fixtures for the roads tests: the committed road files and temporary documents."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from sensorgap.roads import RoadNetwork, read_opendrive

from .builders import ROADS_DIR


@pytest.fixture
def write_xodr(tmp_path: Path) -> Callable[..., Path]:
    """Write text to ``tmp_path/name`` and return the path."""

    def write(text: str, name: str = "test.xodr") -> Path:
        path = tmp_path / name
        path.write_text(text, encoding="utf-8")
        return path

    return write


@pytest.fixture
def load_xodr(write_xodr: Callable[..., Path]) -> Callable[..., RoadNetwork]:
    """Write a document to a temporary file and read it."""

    def load(text: str, name: str = "test.xodr") -> RoadNetwork:
        return read_opendrive(write_xodr(text, name))

    return load


@pytest.fixture(scope="session")
def motorway() -> RoadNetwork:
    return read_opendrive(ROADS_DIR / "motorway_r500.xodr")


@pytest.fixture(scope="session")
def rural() -> RoadNetwork:
    return read_opendrive(ROADS_DIR / "rural_two_lane.xodr")


@pytest.fixture(scope="session")
def urban() -> RoadNetwork:
    return read_opendrive(ROADS_DIR / "urban_junction.xodr")
