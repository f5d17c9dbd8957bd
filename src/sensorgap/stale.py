"""Removing what a command's new output makes stale, shared by the commands
(``search``, ``export``) and the main job (``sensorgap run``), which calls the search and
the export directly: a resumed search that changes the ranking makes the previous export
and report stale; an export that changes the scenario files makes the previous report
stale (its figures ``report/scenario_NNN.png`` of scenarios no longer exported stayed,
listed in the manifest)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

from sensorgap.filesio import remove_outputs
from sensorgap.provenance import sha256_of

T = TypeVar("T")


def catalog_digests(folder: Path) -> dict[str, str]:
    """SHA-256 of each scenario file and of ``catalog.json`` in ``folder`` (relative
    path -> digest; what a report of the folder describes and links): an export that
    changes any of them makes the report stale."""
    paths = sorted((folder / "scenarios").glob("*.xosc"))
    if (folder / "catalog.json").is_file():
        paths.append(folder / "catalog.json")
    return {
        p.relative_to(folder).as_posix(): sha256_of(p)
        for p in paths
        if p.is_file() and not p.is_symlink()
    }


def export_removing_stale_report(folder: Path, export: Callable[[], T]) -> tuple[T, list[str]]:
    """Run ``export`` (an export writing its catalog into ``folder``); when it changed
    the scenario files or ``catalog.json``, remove the previous report of ``folder``
    (``report.build.REPORT_WRITES``: it describes and links the previous export's
    files). Returns (what ``export`` returned, the removed files' relative paths)."""
    from sensorgap.report.build import REPORT_WRITES

    before = catalog_digests(folder)
    result = export()
    gone = remove_outputs(folder, REPORT_WRITES) if before != catalog_digests(folder) else []
    return result, gone


def ranking_of(folder: Path) -> bytes | None:
    """The bytes of ``folder/ranking.json`` (None when there is none): compared after a
    resumed search (``search_removing_stale``)."""
    ranking = folder / "ranking.json"
    return ranking.read_bytes() if ranking.is_file() else None


def stale_after_search() -> tuple[str, ...]:
    """Relative paths of the export and the report (``EXPORT_WRITES``,
    ``REPORT_WRITES``): stale once a search changed the ranking."""
    from sensorgap.export.catalog import EXPORT_WRITES
    from sensorgap.report.build import REPORT_WRITES

    return (*EXPORT_WRITES, *REPORT_WRITES)


def search_removing_stale(folder: Path, search: Callable[[], T]) -> tuple[T, list[str] | None]:
    """Run ``search`` (a search into ``folder``, resuming an earlier one or not); when it
    changed an earlier ``ranking.json``, remove the previous export and report
    (``stale_after_search``). Returns (what ``search`` returned, the removed files' relative
    paths, or None when the ranking did not change)."""
    before = ranking_of(folder)
    result = search()
    if before is None or ranking_of(folder) == before:
        return result, None
    return result, remove_outputs(folder, stale_after_search())
