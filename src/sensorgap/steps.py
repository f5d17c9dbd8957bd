"""The steps that write a certified folder, as the command line (``sensorgap search``,
``export``, ``report --run``) and the facade (``find_scenarios``, ``export_catalog``,
``write_report``) both run them: the
checks before any work, the work, the removal of what it made stale, and the folder's
manifest, written together or not at all.

Hostile rounds 30 and 31: ``find_scenarios(..., resume=True)`` into an exported run left
the previous export and an outdated manifest (``verify`` failed); ``export_catalog`` kept a
report of the previous export (certified by ``verify``) and removed a symbolic link the
command refuses. The command line did each right; one function per step now serves both.
"""

from __future__ import annotations

from collections.abc import Callable
from contextlib import ExitStack, suppress
from pathlib import Path
from typing import TYPE_CHECKING, Any

from sensorgap.atomic import atomic_write_bytes, removed_on_error
from sensorgap.filesio import (
    MANIFEST_NAME,
    refuse_crowded_out,
    refuse_if_changed,
    refuse_inside_certified,
    refuse_links,
    refuse_uncertifiable,
    write_manifest,
)
from sensorgap.locks import folder_lock, held_until_done
from sensorgap.runtime import DeferredStop
from sensorgap.search.run import SEARCH_WRITES
from sensorgap.search.runfolder import RANKING_FILES, RUN_JSON, STORE_FILE
from sensorgap.search.store import ranking_record, restore_ranking_record
from sensorgap.stale import (
    export_removing_stale_report,
    search_removing_stale,
    stale_after_search,
)

if TYPE_CHECKING:
    from sensorgap.search.run import SearchOutcome

#: The option names the steps' refusals give (the command line's; the facade names its
#: parameters instead, ``api._file_errors_as_input``).
OUT, RUN = "--out", "--run"


def _small_files(folder: Path, names: tuple[str, ...]) -> dict[str, bytes | None]:
    """The bytes of the files ``names`` of ``folder`` (None: absent), to ``_put_back``."""
    return {n: (folder / n).read_bytes() if (folder / n).is_file() else None for n in names}


def _put_back(folder: Path, saved: dict[str, bytes | None]) -> None:
    """The files ``_small_files`` read, as they were (best effort: the failure being
    reported is the search's)."""
    for name, data in saved.items():
        with suppress(OSError):
            if data is None:
                (folder / name).unlink(missing_ok=True)
            elif not (folder / name).is_file() or (folder / name).read_bytes() != data:
                atomic_write_bytes(folder / name, data)


def certified_search(
    out: Path, resume: bool, search: Callable[[DeferredStop], SearchOutcome]
) -> tuple[SearchOutcome, list[str] | None]:
    """Run ``search`` (a search into the run folder ``out``, given the ``DeferredStop``
    it holds stop signals with from the recording of its ranking on) as a certified step:

    - before any work: ``out`` is not a crowded folder nor inside another certified
      folder, and, resuming, no file the search rewrites was changed by hand (the new
      manifest would certify it); ``out``, when it exists, is locked for the whole step
      (a search alone releases its lock before the manifest is written);
    - after it: when it changed an earlier ranking, the previous export and report are
      removed (``stale.search_removing_stale``), and the manifest lists the folder;
    - a failure after the search started, resuming, puts back the ranking files,
      ``run.json``, the manifest and the store's record of the ranking (hostile round
      nineteen, F5: they were a mix of the old and the new ranking); its candidates stay
      stored. A stop signal during the last writes is held until they are all written.

    Returns (what ``search`` returned, the removed files' relative paths or None when
    the ranking did not change)."""
    with held_until_done(), ExitStack() as locks:
        if out.is_dir():  # a new folder: the search locks it, held until the block ends
            locks.enter_context(folder_lock(out))
        refuse_crowded_out(out, "search")
        refuse_inside_certified(out, "search")
        if resume:  # the new manifest must not certify a file changed by hand
            refuse_if_changed(out, SEARCH_WRITES)
        resumed = resume and out.is_dir()
        record = ranking_record(out / STORE_FILE) if resumed else {}
        before = _small_files(out, (*RANKING_FILES, MANIFEST_NAME, RUN_JSON)) if resumed else {}
        try:
            # the ranking files, their record in the store, the removal of the stale export
            # and report and the manifest: all written, or (stopped before them) none
            with DeferredStop() as stop:
                outcome, gone = search_removing_stale(out, lambda: search(stop))
                # what export, simulate and report made of the previous ranking no longer
                # matches
                stale: tuple[str, ...] = () if gone is None else stale_after_search()
                write_manifest(out, (*SEARCH_WRITES, *stale) if resume else None)
        except Exception:
            if resumed:
                _put_back(out, before)
                restore_ranking_record(out / STORE_FILE, record)
            raise
    return outcome, gone


def certified_export(
    run: Path, out: Path | None, osc_version: str, top: int | None, style: str
) -> tuple[dict[str, Any], list[str]]:
    """The catalog of the run folder ``run`` (``export.export_catalog``) into ``out``, or
    into ``run`` itself when ``out`` is None, as a certified step:

    - before any work: the folder is not crowded, can be certified, holds no symbolic link
      (hostile round fifteen: ``RUN/scenarios/x``, a link, was removed and the run then
      failed its own ``verify``), and a new ``out`` is not inside another certified folder
      (but its own run, whose export says more); an existing folder is locked for the step;
    - a failed export leaves no partial catalog: a folder it made removed, the scenario
      files, maps, ``catalog.json`` and ``manifest.json`` of an earlier export back;
    - when it changed the scenario files or ``catalog.json``, the folder's previous report
      (which describes and links the previous export's files, their OpenSCENARIO version
      and style) is removed and the manifest rewritten.

    Returns (the catalog index, the removed report files' relative paths)."""
    from sensorgap.export import export_catalog
    from sensorgap.export.catalog import EXPORT_WRITES, refuse_linked_paths
    from sensorgap.report.build import REPORT_WRITES

    folder = out or run
    with held_until_done(), ExitStack() as locks:
        if folder.is_dir():
            locks.enter_context(folder_lock(folder))
        refuse_crowded_out(folder, "export", OUT if out else RUN)
        refuse_uncertifiable(folder, OUT if out else RUN)
        # a link anywhere in the folder it certifies; the paths it writes first, whose
        # lines say more
        if folder.is_dir():
            refuse_linked_paths(folder)
        refuse_links(folder, OUT if out else RUN, "export")
        if out is not None and run.resolve() not in out.resolve().parents:
            refuse_inside_certified(out, "export")  # (inside its own run: export says so)
        with removed_on_error(folder, lock=out is not None):
            index, gone = export_removing_stale_report(
                folder,
                lambda: export_catalog(run, out, osc_version=osc_version, top=top, style=style),
            )
            if gone:
                write_manifest(folder, (*EXPORT_WRITES, *REPORT_WRITES))
    return index, gone


def certified_report(run: Path) -> tuple[Path, Path]:
    """``report.html`` and ``report.md`` of the run folder ``run`` (``report.write_report``)
    as a certified step: no file the report rewrites changed by hand (the new manifest would
    certify it) and the folder certifiable, checked before any work; the folder locked for
    the step; a failed report leaves it as it was (no figure of it left behind, the earlier
    report and manifest back in place); the manifest lists the new report. Returns their
    paths."""
    from sensorgap.report import write_report
    from sensorgap.report.build import REPORT_WRITES

    with held_until_done(), ExitStack() as locks:
        if run.is_dir():
            locks.enter_context(folder_lock(run))
        refuse_crowded_out(run, "report", RUN)  # (hostile round 32: 45 s, then listed)
        refuse_if_changed(run, REPORT_WRITES)
        refuse_uncertifiable(run, RUN)
        with removed_on_error(run, lock=False):
            paths = write_report(run)
            write_manifest(run, REPORT_WRITES)
    return paths
