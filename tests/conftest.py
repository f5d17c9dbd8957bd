"""Shared fixtures: the shipped presets, scenes and a hardened numpy error state."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest

from sensorgap.config import load_environment, load_target
from sensorgap.coverage import Scene
from sensorgap.models import Conditions, System, load_system


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
