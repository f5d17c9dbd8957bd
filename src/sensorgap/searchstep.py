"""The search step of a run folder, as ``sensorgap search`` and the facade's
``find_scenarios`` both run it: the checks before any work, the search, the removal of
the export and report a resumed search made stale, and the folder's manifest, written
together or not at all.

Hostile round 30 (F5): ``find_scenarios(..., resume=True)`` into a certified, exported run
rewrote the ranking files and the store but neither removed the previous export nor
rewrote the manifest, and ``verify`` of the run failed; the command line did all three.
One function now does them for both.
"""

from __future__ import annotations

from collections.abc import Callable
from contextlib import ExitStack, suppress
from pathlib import Path
from typing import TYPE_CHECKING

from sensorgap.atomic import atomic_write_bytes, folder_lock, held_until_done
from sensorgap.filesio import (
    MANIFEST_NAME,
    refuse_crowded_out,
    refuse_if_changed,
    refuse_inside_certified,
    write_manifest,
)
from sensorgap.runtime import DeferredStop
from sensorgap.search.run import SEARCH_WRITES
from sensorgap.search.runfolder import RANKING_FILES, RUN_JSON, STORE_FILE
from sensorgap.search.store import ranking_record, restore_ranking_record
from sensorgap.stale import search_removing_stale, stale_after_search

if TYPE_CHECKING:
    from sensorgap.search.run import SearchOutcome


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
