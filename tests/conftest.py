"""Shared fixtures: the shipped presets, scenes and a hardened numpy error state; the
grouping of tests for parallel workers (pytest-xdist, ``make test``)."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from sensorgap.config import load_environment, load_target
from sensorgap.coverage import Scene
from sensorgap.models import Conditions, System, load_system

TESTS = Path(__file__).resolve().parent
#: Folders whose files share costly session-scoped fixtures (a conftest.py beside them):
#: their tests run on one worker, so each fixture is built once per session.
SHARED_FIXTURE_DIRS = ("export", "report")


#: Tests (node-id prefixes) that share no module- or session-scoped fixture with the rest of
#: their file or folder and take several seconds each: each is a group of its own, so the
#: two workers can split them (a whole file of them on one worker made the longer chain).
OWN_GROUP = (
    "tests/test_determinism.py::",
    "tests/test_hostile_runtime.py::",
    "tests/search/test_credible.py::test_ranked_rows_reproduce_with_evaluate",
    "tests/search/test_credible.py::test_system_a_ranked_bodies_are_unseen",
    "tests/report/test_summary.py::test_summary_names_the_rear_blind_wedges",
)
#: The groups of more than ~2.5 s, longest first (CPU seconds of one worker, 2-core machine,
#: with coverage, 2026-11-26), started in this order, the short ones after them: xdist's
#: own order (most tests first) started the long one-test groups last, and whichever worker
#: took the last of them finished up to 12 s after the other. A folder or file names its
#: group; an entry with "::" is a node-id prefix of a one-test group (``OWN_GROUP``).
LONG_GROUPS = (
    "tests/report",  # 60
    "tests/test_atomicity.py",  # 23 (measured without coverage)
    "tests/export",  # 19
    "tests/test_bad_inputs.py",  # 15
    "tests/search/test_credible.py",  # 11
    "tests/search/test_occluded.py",  # 11
    "tests/test_determinism.py::test_byte_identical_outputs[search+export+report]",  # 10
    "tests/search/test_compare_maps.py",  # 9
    "tests/search/test_credible.py::test_ranked_rows_reproduce_with_evaluate",  # 9
    "tests/test_crash_safety.py",  # 9
    "tests/cli/test_run_vehicle.py",  # 9
    "tests/search/test_credible.py::test_system_a_ranked_bodies_are_unseen",  # 8
    "tests/analysis/test_nearfield.py",  # 7
    "tests/search/test_executors.py",  # 7
    "tests/search/test_runfolder.py",  # 7
    "tests/search/test_search.py",  # 6
    "tests/cli/test_paper.py",  # 5
    "tests/search/test_batch.py",  # 5
    "tests/test_hostile_runtime.py::test_report_and_export_do_not_certify",  # 4
    "tests/cli/test_cli.py",  # 4
    "tests/test_determinism.py::test_byte_identical_outputs[nearfield]",  # 3
    "tests/test_tradeoff.py",  # 3
    "tests/test_api_docs.py",  # 3
    "tests/report/test_summary.py::test_summary_names_the_rear_blind_wedges",  # 3
    "tests/models/test_sweep.py",  # 3
    "tests/test_hostile_runtime.py::test_a_resumed_search_that_changes",  # 3
)


def xdist_group_of(nodeid: str) -> str:
    """The parallel-worker group of a test (its pytest node id, relative to the rootdir):
    the test itself when listed in ``OWN_GROUP``; its folder under tests/ when that folder
    shares session fixtures (``SHARED_FIXTURE_DIRS``); else its file."""
    if nodeid.startswith(OWN_GROUP):
        return nodeid
    path = nodeid.split("::", 1)[0]
    parts = path.split("/")
    if len(parts) > 2 and parts[0] == "tests" and parts[1] in SHARED_FIXTURE_DIRS:
        return "/".join(parts[:2])
    return path


def long_rank(group: str) -> int:
    """The place of a group in ``LONG_GROUPS`` (``len(LONG_GROUPS)``: not listed)."""
    for i, entry in enumerate(LONG_GROUPS):
        if group == entry or ("::" in entry and group.startswith(entry)):
            return i
    return len(LONG_GROUPS)


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config: pytest.Config, log: Any) -> Any:
    """Under ``pytest -n N --dist loadgroup`` (``make test``): whole groups
    (``xdist_group_of``) go to one worker, so module- and session-scoped fixtures are built
    once per session, not once per worker. (pytest-xdist's own ``xdist_group`` marks do not
    reach its scheduler under pytest 9, which keeps node ids elsewhere; this hook is
    xdist's public way to choose the grouping.) Other ``--dist`` modes are left alone."""
    if config.getvalue("dist") != "loadgroup":
        return None
    from xdist.scheduler import LoadScopeScheduling

    class FileOrFolderScheduling(LoadScopeScheduling):  # type: ignore[misc]
        def _split_scope(self, nodeid: str) -> str:
            return xdist_group_of(nodeid)

        def _assign_work_unit(self, node: Any) -> None:
            # the longest groups first (``LONG_GROUPS``), then xdist's order (most tests)
            first = min(self.workqueue, key=long_rank)
            if long_rank(first) < len(LONG_GROUPS):
                self.workqueue.move_to_end(first, last=False)
            super()._assign_work_unit(node)

    return FileOrFolderScheduling(config, log)


def pytest_configure(config: pytest.Config) -> None:
    """With parallel workers (``-n N``), fill numba's kernel cache once before they start
    when it is empty (a fresh clone): tests/numba_warmup.py, in its own process. Not in the
    workers themselves, not without ``-n``."""
    if hasattr(config, "workerinput") or not config.getoption("numprocesses", None):
        return
    from tests.numba_warmup import cache_is_warm, warmup_running

    # a warm-up still running (``make test`` starts it beside mypy and goes on): the
    # workers wait for it after collecting (``pytest_collection_finish``)
    if not cache_is_warm() and not warmup_running():
        subprocess.run(
            [sys.executable, "-m", "tests.numba_warmup"],
            cwd=TESTS.parent,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            check=False,
        )


def pytest_collection_finish(session: pytest.Session) -> None:
    """A parallel worker, its tests collected, waits for a numba warm-up that is still
    running (``tests/numba_warmup.py``): its kernels then load from the cache instead of
    compiling under coverage tracing in every worker."""
    if hasattr(session.config, "workerinput"):
        from tests.numba_warmup import wait_for_warmup

        wait_for_warmup()


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


def make_scene(
    system: System, target: str = "car", env: str = "clear", heading: float = 0.0
) -> Scene:
    """A scene from preset names."""
    return Scene(
        system, load_target(target), Conditions.from_config(load_environment(env), heading)
    )
