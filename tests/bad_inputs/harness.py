"""Preparing and checking the cases of the bad-input corpus (``cases.toml``, format in
README.md), shared by ``tests/test_bad_inputs.py`` (in process) and
``benchmarks/bench_corpus.py`` (each case in a fresh child process).

``prepare_case`` builds a case's folder, output path and run-folder copy, its argv with
the placeholders replaced and its ``setup`` steps done; ``outcome_problems`` says what is
wrong with the exit code and stderr a case gave (empty: the case passed). Neither runs
the case itself. Commands a setup step runs (``existing_search``) go through a
``run_cli`` callable, so a caller decides in which process they run. This module imports
nothing of sensorgap at import time (a benchmark's parent process stays small: a child's
``ru_maxrss`` is at least its parent's resident size when it was started).
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import resource
import shutil
import sqlite3
import tomllib
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
CASES_FILE = HERE / "cases.toml"

#: Runs ``sensorgap`` with an argv and returns its exit code.
RunCli = Callable[[list[str]], int]

#: Arguments of the small finished search run that ``{run}`` copies: System B on a rural
#: curve into the low sun (a sensor-critical scenario to export), its near field and
#: its export. ``{out}`` is the run folder.
FINISHED_RUN_COMMANDS: tuple[tuple[str, ...], ...] = (
    (
        "search",
        "--vehicle",
        "system_b",
        "--families",
        "stopped_rural_curve",
        "--environments",
        "snow",
        "--budget",
        "100",
        "--top",
        "2",
        "--strategy",
        "lhs",
        "--out",
        "{out}",
    ),
    ("nearfield", "--vehicle", "system_b", "--resolution", "0.2", "--out", "{out}/nearfield"),
    ("export", "--run", "{out}"),
)

#: Characters of the ``{long}`` placeholder: an option value of 100 kB.
LONG_VALUE_CHARS = 100_000
#: Longest error line a case may give, characters (a quoted value is cut to 80, a named
#: file to about 200: ``sensorgap.errors.clip``).
MAX_LINE_CHARS = 1_000

#: Where a case's ``stdout`` field sends the command's standard output (``closed``: none,
#: file descriptor 1 not open, as after ``>&-``: ``sys.stdout`` is None in process).
STDOUT_KINDS = ("full", "closed_pipe", "closed")


class CaseError(Exception):
    """A case of the corpus is itself wrong (an unknown setup step, a replacement whose
    text is not in its file): a fault of the corpus, not of sensorgap."""


def load_cases(path: Path = CASES_FILE) -> list[dict[str, Any]]:
    """Every ``[[case]]`` of the corpus, in file order."""
    cases: list[dict[str, Any]] = tomllib.loads(path.read_text(encoding="utf-8"))["case"]
    return cases


#: Setup steps that work on the finished run although the argv does not name ``{run}``.
RUN_SETUP_STEPS = ("export_into_out", "job_folder_from_run", "nearfield_as_out")


def needs_run(case: dict[str, Any]) -> bool:
    """Whether the case works on a copy of the finished run (``{run}`` in its argv or its
    ``unchanged``, or a setup step that exports or copies it)."""
    return any("{run}" in a for a in [*case["argv"], *case.get("unchanged", [])]) or any(
        step in RUN_SETUP_STEPS for step in case.get("setup", [])
    )


def build_finished_run(out: Path, run_cli: RunCli) -> Path:
    """The small finished, exported search run with a near-field analysis and a manifest
    that ``{run}`` copies, made in ``out`` by ``FINISHED_RUN_COMMANDS``."""
    for command in FINISHED_RUN_COMMANDS:
        argv = [a.replace("{out}", str(out)) for a in command]
        code = run_cli(argv)
        if code != 0:
            raise CaseError(f"building the finished run: exit {code} from {argv}")
    return out


@dataclass
class Prepared:
    """A case made ready to run: its argv (placeholders replaced), its folder ``{dir}``,
    output path ``{out}`` and run copy ``{run}``, the files below ``{out}`` before the
    command runs, whether ``{out}`` existed then, and the state (``tree_state``) of each
    folder the case's ``unchanged`` names."""

    case: dict[str, Any]
    argv: list[str]
    folder: Path
    out: Path
    run: Path
    before: set[str]
    #: the case's ``env`` (variables set for the command), placeholders replaced
    env: dict[str, str]
    out_existed: bool = False
    unchanged: dict[str, dict[str, str]] = field(default_factory=dict)


def prepare_case(
    case: dict[str, Any], tmp: Path, finished_run: Path | None, run_cli: RunCli
) -> Prepared:
    """Make ``case`` ready to run in the empty folder ``tmp``: its files, the run copy and
    its edits, the argv, the setup steps (``run_cli`` runs the commands they need). A case
    on ``{run}`` needs ``finished_run`` (``build_finished_run``)."""
    folder = tmp / "case"
    folder.mkdir()
    out = tmp / "out"
    run = tmp / "run"
    if needs_run(case):
        if finished_run is None:
            raise CaseError(f"{case['name']}: needs the finished run ({{run}})")
        shutil.copytree(finished_run, run)
    _write_files(case, folder)
    if run.is_dir():
        _edit_run(case, run)
        if case.get("drop_manifest"):  # a file's own check, not the folder's integrity
            (run / "manifest.json").unlink()
        if case.get("drop_manifest") or case.get("forge_records"):
            _forge_records(run)
        if case.get("rehash_manifest"):
            _rehash_manifest(run)
    subs = {
        "{dir}": str(folder),
        "{out}": str(out),
        "{run}": str(run),
        "{templates}": str(REPO / "templates"),
        "{roads}": str(REPO / "roads"),
        "{long}": "a" * LONG_VALUE_CHARS,
        "{zeros}": "0" * 5000,
    }

    def sub(text: str) -> str:
        for k, v in subs.items():
            text = text.replace(k, v)
        return text

    argv = [sub(a) for a in case["argv"]]
    env = {name: sub(value) for name, value in case.get("env", {}).items()}
    _setup(case, argv, folder, out, run, run_cli)
    unchanged = {}
    for name in case.get("unchanged", []):
        if name not in ("{run}", "{out}"):
            raise CaseError(f"{case['name']}: unchanged names {{run}} or {{out}}, got {name!r}")
        unchanged[name] = tree_state(run if name == "{run}" else out)
    return Prepared(
        case, argv, folder, out, run, files_below(out), env, os.path.lexists(out), unchanged
    )


def fsize_limiter(case: dict[str, Any]) -> Callable[[], None] | None:
    """For a case with ``rlimit_fsize``: a ``preexec_fn`` that caps the size of any file
    the child writes (a full disk); else None."""
    if "rlimit_fsize" not in case:
        return None
    limit = int(case["rlimit_fsize"])

    def cap() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    return cap


def _gone(prepared: Prepared) -> Path:
    """The working directory of a case with ``cwd = "deleted"``: made, entered, removed."""
    return prepared.folder / "gone"


def child_preexec(prepared: Prepared) -> Callable[[], None] | None:
    """The ``preexec_fn`` of a case run in a child process: ``rlimit_fsize``
    (``fsize_limiter``), ``stdout = "closed"`` (file descriptor 1 closed) and
    ``cwd = "deleted"`` (the child enters a folder and removes it); None when the case
    needs none of them."""
    case = prepared.case
    cap = fsize_limiter(case)
    close_stdout = case.get("stdout") == "closed"
    gone = _gone(prepared) if case.get("cwd") == "deleted" else None
    if cap is None and not close_stdout and gone is None:
        return None

    def before_exec() -> None:
        if cap is not None:
            cap()
        if close_stdout:
            os.close(1)
        if gone is not None:
            gone.mkdir()
            os.chdir(gone)
            gone.rmdir()

    return before_exec


@contextmanager
def case_cwd(prepared: Prepared) -> Iterator[None]:
    """In process: a case with ``cwd = "deleted"`` runs in a working directory that no
    longer exists (entered, then removed; the caller's restored afterwards). Other values
    are refused; no field: nothing changes."""
    kind = prepared.case.get("cwd")
    if kind is None:
        yield
        return
    if kind != "deleted":
        raise CaseError(f"{prepared.case['name']}: cwd must be 'deleted', got {kind!r}")
    before = os.getcwd()
    gone = _gone(prepared)
    gone.mkdir()
    os.chdir(gone)
    gone.rmdir()
    try:
        yield
    finally:
        os.chdir(before)


@contextmanager
def case_stdout(case: dict[str, Any]) -> Iterator[TextIO | None]:
    """The standard output a case's ``stdout`` field asks for, open while the block runs:
    ``full`` (``/dev/full``: every write fails with ENOSPC once the buffer is flushed) or
    ``closed_pipe`` (a pipe whose read end is closed: EPIPE); None without the field (the
    caller's own, and for ``closed``, which a child gets from ``child_preexec`` and an
    in-process run as ``sys.stdout = None``). Closed afterwards, its failing flush
    ignored."""
    kind = case.get("stdout")
    if kind is None or kind == "closed":  # closed: by child_preexec, or in process None
        yield None
        return
    if kind == "full":
        stream = open("/dev/full", "w", encoding="utf-8")  # noqa: SIM115 - closed below
    elif kind == "closed_pipe":
        read_end, write_end = os.pipe()
        os.close(read_end)
        stream = open(write_end, "w", encoding="utf-8")  # noqa: SIM115 - closed below
    else:
        raise CaseError(f"{case['name']}: stdout must be one of {STDOUT_KINDS}, got {kind!r}")
    try:
        yield stream
    finally:
        with suppress(OSError):
            stream.close()


def error_lines(err: str) -> list[str]:
    """The lines of stderr that count: a run folder's one-line notes and warnings
    (docs/runs.md) are not errors."""
    return [
        ln
        for ln in err.strip().splitlines()
        if not ln.startswith(("sensorgap: note: ", "sensorgap: warning: "))
    ]


def outcome_problems(prepared: Prepared, code: int, err: str) -> list[str]:
    """What is wrong with the outcome of a prepared case (exit ``code``, stderr ``err``):
    the exit code the case expects; one error line per error found (``lines`` if the case
    says, at least one), each ``sensorgap...: error: ...`` of at most ``MAX_LINE_CHARS``
    characters, the first matching ``message``; no traceback; no temporary file below
    ``{out}`` and, for exit 2, no file there that was not there before; a symbolic-linked
    output folder unchanged. The first problem found only (as one assertion after another
    would): empty when the case passed."""
    case = prepared.case
    lines = error_lines(err)
    if code != case["exit"]:
        return [f"exit {code}: {err}"]
    if "lines" in case and len(lines) != int(case["lines"]):
        return [f"{len(lines)} lines, expected {case['lines']}: {err}"]
    if not lines:
        return [f"no error line: {err}"]
    if not all(ln.startswith("sensorgap") and ": error: " in ln for ln in lines):
        return [f"not an error line: {err[:2000]}"]
    too_long = [ln for ln in lines if len(ln) > MAX_LINE_CHARS]
    if too_long:
        return [f"an error line of {len(too_long[0])} characters: {too_long[0][:300]}..."]
    if "Traceback" in err:
        return [f"a traceback: {err}"]
    if not re.search(case["message"], lines[0]):
        return [f"message does not match {case['message']!r}: {lines[0]}"]
    after = files_below(prepared.out)
    tmp_files = sorted(f for f in after if ".tmp" in f)
    if tmp_files:
        return [f"temporary files left: {tmp_files}"]
    if code == 2 and not after <= prepared.before:
        return [f"files written despite the error: {sorted(after - prepared.before)}"]
    if code == 2 and not prepared.out_existed and os.path.lexists(prepared.out):
        left = sorted(p.relative_to(prepared.out).as_posix() for p in prepared.out.rglob("*"))
        return [f"{{out}} did not exist and was left behind, holding {left[:5]}"]
    for name, state in prepared.unchanged.items():
        now = tree_state(prepared.run if name == "{run}" else prepared.out)
        if now != state:
            diff = sorted(k for k in {*state, *now} if state.get(k) != now.get(k))
            return [f"{name} changed: {diff[:5]}"]
    elsewhere = prepared.folder / "elsewhere"
    if elsewhere.is_dir() and files_below(elsewhere) != {"keep.xodr"}:
        return [f"the symbolic-linked folder changed: {sorted(files_below(elsewhere))}"]
    return []


def tree_state(folder: Path) -> dict[str, str]:
    """Every entry below ``folder`` (relative POSIX path): a file's SHA-256, ``dir`` for a
    folder, ``link`` for a symbolic link (not followed); empty when ``folder`` does not
    exist. Equal states: the folder was left exactly as it was."""
    state: dict[str, str] = {}
    if not folder.is_dir():
        return state
    for dirpath, dirnames, filenames in os.walk(folder):
        for name in [*dirnames, *filenames]:
            p = Path(dirpath) / name
            rel = p.relative_to(folder).as_posix()
            if p.is_symlink():
                state[rel] = "link"
            elif p.is_dir():
                state[rel] = "dir"
            else:
                state[rel] = hashlib.sha256(p.read_bytes()).hexdigest()
    return state


def files_below(folder: Path) -> set[str]:
    """Relative POSIX paths of the files below ``folder`` (empty if it is not a folder)."""
    return (
        {p.relative_to(folder).as_posix() for p in folder.rglob("*") if p.is_file()}
        if folder.is_dir()
        else set()
    )


# -- files and run edits ---------------------------------------------------------------


def _write_files(case: dict[str, Any], folder: Path, key: str = "files") -> None:
    for name, spec in case.get(key, {}).items():
        if isinstance(spec, str):
            text = spec
        else:
            text = (REPO / spec["from"]).read_text(encoding="utf-8")
            for old, new in spec.get("replace", []):
                if old not in text:
                    raise CaseError(f"{case['name']}: {old!r} not in {spec['from']}")
                text = text.replace(old, new)
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        (folder / name).write_text(_big_numbers(text), encoding="utf-8")


#: Placeholders of integers too large to write in a case: 400 digits (beyond a float) and
#: 5,000 (beyond Python's 4,300-digit ``int(str)`` limit), in ``files`` and ``run_edit``.
BIG_NUMBERS = {"{ones400}": "1" * 400, "{ones5000}": "1" * 5000}


def _big_numbers(text: str) -> str:
    for key, digits in BIG_NUMBERS.items():
        text = text.replace(key, digits)
    return text


def _edit_manifest(run: Path, entry: str) -> None:
    manifest = json.loads((run / "manifest.json").read_text())
    manifest["files"][entry] = {"bytes": 4, "sha256": "0" * 64}
    (run / "manifest.json").write_text(json.dumps(manifest))


def _edit_run(case: dict[str, Any], run: Path) -> None:
    """``run_files`` (inline text written into ``{run}``), ``run_edit`` ([file, regex,
    replacement]: the first match replaced) and ``run_input_edit`` (a recorded input's
    copy edited, [old, new] pairs, with its SHA-256 in run.json updated to match, under
    every label recording that copy)."""
    for name, text in case.get("run_files", {}).items():
        (run / name).write_text(text, encoding="utf-8")
    for name, pattern, repl in case.get("run_edit", []):
        repl = _big_numbers(repl)
        text, n = re.subn(pattern, repl, (run / name).read_text(encoding="utf-8"), count=1)
        if n != 1:
            raise CaseError(f"{case['name']}: {pattern!r} not in {name}")
        (run / name).write_text(text, encoding="utf-8")
    for label, pairs in case.get("run_input_edit", {}).items():
        info = json.loads((run / "run.json").read_text())
        copy = run / info["inputs"][label]["copy"]
        text = copy.read_text(encoding="utf-8")
        for old, new in pairs:
            if old not in text:
                raise CaseError(f"{case['name']}: {old!r} not in {copy.name}")
            text = text.replace(old, new)
        copy.write_text(text, encoding="utf-8")
        digest = hashlib.sha256(copy.read_bytes()).hexdigest()
        for entry in info["inputs"].values():  # every label of that copy (reaction, friction)
            if isinstance(entry, dict) and entry.get("copy") == info["inputs"][label]["copy"]:
                entry["sha256"] = digest
        (run / "run.json").write_text(json.dumps(info))


def _rehash_manifest(run: Path) -> None:
    """Every entry of ``{run}``'s manifest re-hashed to its file as it is now (an edit
    made to look certified: only the run's own records can tell)."""
    manifest = json.loads((run / "manifest.json").read_text(encoding="utf-8"))
    for rel in manifest["files"]:
        data = (run / rel).read_bytes()
        manifest["files"][rel] = {"bytes": len(data), "sha256": hashlib.sha256(data).hexdigest()}
    (run / "manifest.json").write_text(json.dumps(manifest, indent=2), encoding="utf-8")


def _forge_records(run: Path) -> None:
    """``run`` as a forger leaves it after editing files: the SHA-256 records of its
    ranking files (the store's meta row ``ranking_files``) and of its catalog's files
    (``catalog.json``'s ``files``) recomputed for the files as they are now, so an
    edited ranking or scenario meets the checks of its rows, not those of the records.
    (The records are required: a store or catalog without them is refused, hostile round
    twenty, F2; these cases removed them before.)"""
    store = run / "search.sqlite"
    if store.is_file():
        con = sqlite3.connect(store)
        try:
            row = con.execute("SELECT value FROM meta WHERE key = 'ranking_files'").fetchone()
            if row is not None:
                record = json.loads(row[0])
                for name in list(record):
                    if (run / name).is_file():
                        record[name] = hashlib.sha256((run / name).read_bytes()).hexdigest()
                con.execute(
                    "UPDATE meta SET value = ? WHERE key = 'ranking_files'",
                    (json.dumps(record, sort_keys=True),),
                )
                con.commit()
        finally:
            con.close()
    if (run / "catalog.json").is_file():
        try:
            index = json.loads((run / "catalog.json").read_text(encoding="utf-8"))
        except ValueError:  # a case's own catalog.json may be anything
            return
        files = index.get("files") if isinstance(index, dict) else None
        if isinstance(files, dict):
            for rel, meta in files.items():
                if isinstance(meta, dict) and (run / rel).is_file():
                    data = (run / rel).read_bytes()
                    meta.update(bytes=len(data), sha256=hashlib.sha256(data).hexdigest())
            (run / "catalog.json").write_text(json.dumps(index, indent=2), encoding="utf-8")


def _sql(db: Path, script: str) -> None:
    con = sqlite3.connect(db)
    con.executescript(script)
    con.close()


def _many_geometries(path: Path, n: int) -> None:
    geoms = "".join(
        f'<geometry s="{i}" x="{i}" y="0" hdg="0" length="1"><line/></geometry>' for i in range(n)
    )
    lanes = (
        '<lanes><laneSection s="0"><center><lane id="0" type="none"/></center><right>'
        '<lane id="-1" type="driving"><width sOffset="0" a="3.5" b="0" c="0" d="0"/>'
        "</lane></right></laneSection></lanes>"
    )
    path.write_text(
        f'<?xml version="1.0"?><OpenDRIVE><header revMajor="1" revMinor="6"/>'
        f'<road id="1" junction="-1" length="{n}"><planView>{geoms}</planView>'
        f"{lanes}</road></OpenDRIVE>"
    )


def _png_bomb(path: Path) -> None:
    """A valid PNG of 10,000 x 10,000 1-bit pixels (12 kB; 1.6 GB to embed: round 25)."""
    import struct
    import zlib

    def chunk(kind: bytes, data: bytes) -> bytes:
        crc = zlib.crc32(kind + data) & 0xFFFFFFFF
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", crc)

    w = h = 10_000
    z = zlib.compressobj(9)
    row = b"\x00" * (1 + (w + 7) // 8)
    data = b"".join(z.compress(row) for _ in range(h)) + z.flush()
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 1, 0, 0, 0, 0))
        + chunk(b"IDAT", data)
        + chunk(b"IEND", b"")
    )


def _coverage_map(folder: Path, damage: str) -> None:
    """A small coverage map (coverage.npz, summary.json) in ``folder`` with one damage:
    ``pd_nan``, ``x_reversed``, ``huge_header`` (pd's .npy header claims 1e10 cells),
    ``summary_nan`` (an area of summary.json is NaN), ``other_vehicle`` (its summary
    names System A; the finished run is System B's), ``resolution_complex``,
    ``resolution_many`` (3 values), ``empty`` (no cell), ``no_summary``."""
    import io
    import zipfile

    import numpy as np

    folder.mkdir(parents=True)
    x, y = np.arange(-59.0, 160.0, 2.0), np.arange(-39.0, 40.0, 2.0)
    arrays = {
        "x": x,
        "y": y,
        "pd": np.zeros((y.size, x.size)),
        "resolution": np.array(2.0),
        "height": np.array(0.75),
    }
    if damage == "pd_nan":
        arrays["pd"][0, 0] = np.nan
    if damage == "x_reversed":
        arrays["x"] = x[::-1].copy()
    if damage == "resolution_complex":  # round 24: a numpy warning
        arrays["resolution"] = np.array([2.0 + 0.0j])
    if damage == "resolution_many":  # round 24: read whole (5 GB at 6e8 values)
        arrays["resolution"] = np.full(3, 2.0)
    if damage == "empty":  # round 24: an internal error in the report's summary
        arrays["x"], arrays["y"], arrays["pd"] = np.zeros(0), np.zeros(0), np.zeros((0, 0))
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        for k, v in arrays.items():
            b = io.BytesIO()
            np.save(b, v)
            data = b.getvalue()
            if damage == "huge_header" and k == "pd":
                hdr = "{'descr': '<f8', 'fortran_order': False, 'shape': (100000, 100000), }"
                hdr = hdr.ljust(117) + "\n"
                data = b"\x93NUMPY\x01\x00" + len(hdr).to_bytes(2, "little") + hdr.encode()
            zf.writestr(f"{k}.npy", data)
    (folder / "coverage.npz").write_bytes(buf.getvalue())
    area = "NaN" if damage == "summary_nan" else "0.0"
    summary = (
        '{"area_m2_by_level": {"pd=1.0": AREA, "pd>=0.8": 0.0, "pd>=0.5": 0.0, "pd>0": 0.0, '
        '"pd=0": 17600.0}, "environment": "clear", "grid": {"resolution_m": 2.0}, '
        '"target": "car", "vehicle": "VEHICLE"}'
    )
    if damage == "other_vehicle":  # another vehicle's map in this run's folder
        summary = summary.replace("VEHICLE", "System A")
    (folder / "summary.json").write_text(
        summary.replace("AREA", area).replace("VEHICLE", "System B")
    )
    if damage == "no_summary":  # round 24: whose map it is could not be checked
        (folder / "summary.json").unlink()


# -- setup steps -----------------------------------------------------------------------


#: The crowded folder of the last case that asked for one (its command refused it before
#: any work): the next such case takes it over by a rename instead of making 100,001
#: files again (2-4 s each, and as long again to delete them later).
_CROWDS: list[Path] = []


def _crowd_into(target: Path) -> None:
    """Make ``target`` a folder of 100,001 empty files ``f0`` .. ``f100000``."""
    while _CROWDS:
        earlier = _CROWDS.pop()
        if earlier.is_dir() and sum(1 for _ in os.scandir(earlier)) == 100_001:
            earlier.rename(target)
            _CROWDS.append(target)
            return
    target.mkdir()
    crowd = os.open(target, os.O_RDONLY | os.O_DIRECTORY)
    try:  # by the folder's descriptor: a fifth of pathlib's touch (5 s)
        for i in range(100_001):
            os.close(os.open(f"f{i}", os.O_CREAT | os.O_WRONLY, 0o644, dir_fd=crowd))
    finally:
        os.close(crowd)
    _CROWDS.append(target)


def _setup(
    case: dict[str, Any], argv: list[str], folder: Path, out: Path, run: Path, run_cli: RunCli
) -> None:
    db = out / "search.sqlite"
    for step in case.get("setup", []):
        if step == "out_parent_is_file":
            out.write_text("a file where a folder is expected")
        elif step == "sparse_huge_road":
            with (folder / "huge.xodr").open("wb") as f:
                f.truncate(300 * 2**20)  # sparse: costs no disk
        elif step == "delete_first_scenario":
            next((run / "scenarios").glob("*.xosc")).unlink()
        elif step == "corrupt_nearfield":
            (run / "nearfield" / "nearfield.json").write_text("{broken")
        elif step == "existing_search":
            code = run_cli([*argv[:-2], "--out", str(out)])
            if code != 0:
                raise CaseError(f"{case['name']}: the existing search gave exit {code}")
            _write_files(case, folder, "files_after")
        elif step == "store_garbage":
            db.write_bytes(b"definitely not an SQLite database " * 200)
        elif step == "store_truncated":
            db.write_bytes(db.read_bytes()[:1500])
        elif step == "store_wrong_schema":
            _sql(db, "DROP TABLE candidates; CREATE TABLE candidates (x TEXT);")
        elif step == "store_bad_json":
            _sql(db, "UPDATE candidates SET params = '{not json' WHERE idx = 0;")
        elif step == "store_param_changed":  # a parameter of row 0 edited, its id kept
            _sql(db, "UPDATE candidates SET params = json_set(params, '$.zz_m', 1) WHERE idx = 0;")
        elif step == "store_not_a_probability":
            _sql(
                db,
                "UPDATE candidates SET metrics = replace(metrics, "
                "'\"mean_pd\": ', '\"mean_pd\": 7') WHERE idx = 0;",
            )
        elif step == "store_feasible_text":
            _sql(db, "UPDATE candidates SET feasible = 'yes' WHERE idx = 0;")
        elif step == "store_empty_metrics":
            _sql(db, "UPDATE candidates SET metrics = '{}' WHERE idx = 0;")
        elif step == "store_deep_json":
            _sql(
                db,
                "UPDATE candidates SET params = '" + "[" * 5000 + "]" * 5000 + "' WHERE idx = 0;",
            )
        elif step.startswith("deep_json:"):  # deep_json:<file in {dir}>
            (folder / step.removeprefix("deep_json:")).parent.mkdir(parents=True, exist_ok=True)
            (folder / step.removeprefix("deep_json:")).write_text("[" * 5000 + "]" * 5000)
        elif step == "huge_vehicle_name":  # a 1 MB name in {dir}/v.toml
            v = folder / "v.toml"
            v.write_text(
                re.sub(r'(?m)^name = ".*"$', 'name = "' + "A" * 2**20 + '"', v.read_text(), count=1)
            )
        elif step == "road_symlink_loop":
            (folder / "loop.xodr").symlink_to(folder / "loop.xodr")
        elif step in ("deep_catalog_json", "deep_ranking_json"):
            name = "catalog.json" if step == "deep_catalog_json" else "ranking.json"
            (run / name).write_text('{"junk": ' + "[" * 5000 + "]" * 5000 + "}")
        elif step == "out_roads_symlink":  # {out}/roads links to {dir}/elsewhere
            (folder / "elsewhere").mkdir()
            (folder / "elsewhere" / "keep.xodr").write_text("not the export's")
            out.mkdir()
            (out / "roads").symlink_to(folder / "elsewhere")
        elif step in ("out_store_symlink", "out_journal_symlink"):
            # {out}/search.sqlite (or its -journal) links to {dir}/elsewhere/store.sqlite
            (folder / "elsewhere").mkdir()
            (folder / "elsewhere" / "keep.xodr").write_text("not the search's")
            out.mkdir(exist_ok=True)
            name = "search.sqlite" if step == "out_store_symlink" else "search.sqlite-journal"
            (out / name).symlink_to(folder / "elsewhere" / "store.sqlite")
        elif step == "run_scenarios_extra_link":  # {run}/scenarios/extra -> ../ranking.json
            (run / "scenarios").mkdir(exist_ok=True)
            (run / "scenarios" / "extra").symlink_to(Path("..") / "ranking.json")
        elif step == "out_holds_a_link":  # {out}/mylink -> {dir}/elsewhere.txt
            (folder / "elsewhere.txt").write_text("not the export's")
            out.mkdir()
            (out / "mylink").symlink_to(folder / "elsewhere.txt")
        elif step == "run_report_symlink":  # {run}/report links to {dir}/elsewhere
            (folder / "elsewhere").mkdir()
            (folder / "elsewhere" / "keep.xodr").write_text("not the report's")
            (run / "report").symlink_to(folder / "elsewhere")
        elif step == "manifest_above_run":  # {run}/.. certified with {run}'s files
            files = json.loads((run / "manifest.json").read_text())["files"]
            listed = {f"run/{rel}": meta for rel, meta in files.items()}
            (run.parent / "manifest.json").write_text(
                json.dumps({"algorithm": "sha256", "files": listed})
            )
        elif step == "out_inputs_symlink":  # {out}/inputs links to {dir}/elsewhere
            (folder / "elsewhere").mkdir()
            (folder / "elsewhere" / "keep.xodr").write_text("not the search's")
            out.mkdir()
            (out / "inputs").symlink_to(folder / "elsewhere")
        elif step == "run_inputs_vehicle_symlink":  # {run}/inputs/vehicle -> {dir}/elsewhere
            (folder / "elsewhere").mkdir()
            (folder / "elsewhere" / "keep.xodr").write_text("not the search's")
            shutil.rmtree(run / "inputs" / "vehicle")
            (run / "inputs" / "vehicle").symlink_to(folder / "elsewhere")
        elif step == "many_environments":  # {dir}/e.toml with 1,001 environments
            (folder / "e.toml").write_text(
                "".join(
                    f"[environments.e{i}]\nvisibility_m = 23000.0\nirradiance_w_m2 = 534.0\n"
                    f'[environments.e{i}.sources]\nvisibility_m = "x"\n'
                    f'irradiance_w_m2 = "x"\n'
                    for i in range(1001)
                )
            )
        elif step == "nearfield_png_symlink":  # {run}/nearfield/nearfield.png -> elsewhere
            (folder / "elsewhere").mkdir()
            (folder / "elsewhere" / "keep.xodr").write_text("not the near field's")
            (run / "nearfield" / "nearfield.png").unlink()
            (run / "nearfield" / "nearfield.png").symlink_to(folder / "elsewhere" / "keep.xodr")
        elif step == "run_catalog_symlink":  # {run}/catalog.json -> {dir}/elsewhere/...
            (folder / "elsewhere").mkdir()
            (folder / "elsewhere" / "keep.xodr").write_text("not the export's")
            (run / "catalog.json").unlink()
            (run / "catalog.json").symlink_to(folder / "elsewhere" / "keep.xodr")
        elif step == "run_report_md_symlink":  # {run}/report.md -> {dir}/elsewhere/...
            (folder / "elsewhere").mkdir()
            (folder / "elsewhere" / "keep.xodr").write_text("not the report's")
            (run / "report.md").symlink_to(folder / "elsewhere" / "keep.xodr")
        elif step == "crowded_dir":  # {dir}/crowd/ holds 100,001 empty files
            _crowd_into(folder / "crowd")
        elif step.startswith("run_store_meta_deleted:"):  # a meta row of {run}'s store
            key = step.removeprefix("run_store_meta_deleted:")
            _sql(run / "search.sqlite", f"DELETE FROM meta WHERE key = '{key}';")
        elif step.startswith("run_store_meta_emptied:"):  # a meta row set to '{}'
            key = step.removeprefix("run_store_meta_emptied:")
            _sql(run / "search.sqlite", f"UPDATE meta SET value = '{{}}' WHERE key = '{key}';")
        elif step == "run_store_deleted":  # {run}/search.sqlite removed
            (run / "search.sqlite").unlink()
        elif step == "templates_with_a_folder_for_system_a":  # {dir}/tpl: a folder there
            from sensorgap.config.presets import templates_dir

            shutil.copytree(templates_dir(), folder / "tpl")
            (folder / "tpl" / "vehicles" / "system_a.toml").unlink()
            (folder / "tpl" / "vehicles" / "system_a.toml").mkdir()
        elif step.startswith("templates_without:"):  # {dir}/tpl lacking one file
            from sensorgap.config.presets import templates_dir

            shutil.copytree(templates_dir(), folder / "tpl")
            (folder / "tpl" / step.removeprefix("templates_without:")).unlink()
        elif step.startswith("templates_renamed_environment:"):  # {dir}/tpl: env renamed
            from sensorgap.config.presets import templates_dir

            name = step.removeprefix("templates_renamed_environment:")
            shutil.copytree(templates_dir(), folder / "tpl")
            envs = folder / "tpl" / "environments.toml"
            text = envs.read_text(encoding="utf-8")
            envs.write_text(text.replace(f"[environments.{name}", f"[environments.{name}_x"))
        elif step.startswith("templates_renamed_target:"):  # {dir}/tpl: a target renamed
            from sensorgap.config.presets import templates_dir

            name = step.removeprefix("templates_renamed_target:")
            shutil.copytree(templates_dir(), folder / "tpl")
            targets = folder / "tpl" / "targets.toml"
            text = targets.read_text(encoding="utf-8")
            targets.write_text(text.replace(f"[targets.{name}", f"[targets.{name}_x"))
        elif step.startswith("roads_only:"):  # {dir}/rd holding one shipped road
            from sensorgap.config.presets import roads_dir

            (folder / "rd").mkdir()
            name = step.removeprefix("roads_only:")
            shutil.copyfile(roads_dir() / f"{name}.xodr", folder / "rd" / f"{name}.xodr")
        elif step == "templates_with_a_broken_family_link":  # {dir}/tpl/scenarios/zz.toml
            from sensorgap.config.presets import templates_dir

            shutil.copytree(templates_dir(), folder / "tpl")
            (folder / "tpl" / "scenarios" / "zz.toml").symlink_to(folder / "nonexistent")
        elif step == "run_nearfield_deleted":  # {run}/nearfield removed
            shutil.rmtree(run / "nearfield")
        elif step == "run_search_killed":  # as SIGKILL leaves a search before its ranking
            for name in ("ranking.json", "ranking.csv", "summary.json", "unavoidable.csv"):
                (run / name).unlink(missing_ok=True)
        elif step == "fifo_out":  # {dir}/out.csv is a named pipe
            os.mkfifo(folder / "out.csv")
        elif step.startswith("dir_fifo:"):  # {dir}/<name> is a named pipe
            os.mkfifo(folder / step.removeprefix("dir_fifo:"))
        elif step == "out_holds_link":  # {out}/figures/a.png links to {dir}/elsewhere/keep.xodr
            (folder / "elsewhere").mkdir()
            (folder / "elsewhere" / "keep.xodr").write_text("not the command's")
            (out / "figures").mkdir(parents=True)
            (out / "figures" / "a.png").symlink_to(folder / "elsewhere" / "keep.xodr")
        elif step == "link_out":  # {dir}/out.csv links to {dir}/elsewhere/keep.xodr
            (folder / "elsewhere").mkdir()
            (folder / "elsewhere" / "keep.xodr").write_text("not the probe's")
            (folder / "out.csv").symlink_to(folder / "elsewhere" / "keep.xodr")
        elif step == "export_into_out":  # {out}: a catalog exported from {run}
            code = run_cli(["export", "--run", str(run), "--out", str(out)])
            if code != 0:
                raise CaseError(f"{case['name']}: the export gave exit {code}")
        elif step == "run_roads_symlink":  # {run}/roads links to {dir}/elsewhere
            (folder / "elsewhere").mkdir()
            (folder / "elsewhere" / "keep.xodr").write_text("not the export's")
            shutil.rmtree(run / "roads")
            (run / "roads").symlink_to(folder / "elsewhere")
        elif step == "many_geometries":
            _many_geometries(folder / "many.xodr", 50_001)
            argv[argv.index(str(folder / "r.xodr"))] = str(folder / "many.xodr")
        elif step == "big_csv_field":
            (folder / "p.csv").write_text("x,y\n1," + "1" * 200_000 + "\n")
        elif step == "manifest_escape":
            _edit_manifest(run, "../../etc/passwd")
        elif step == "manifest_absolute":
            _edit_manifest(run, "/etc/passwd")
        elif step == "symlink_out":
            (run / "etc_link").symlink_to("/etc")
        elif step == "symlink_loop":
            (run / "loop").symlink_to(run / "loop")
        elif step == "journal_file":
            (run / "search.sqlite-journal").write_bytes(b"journal")
        elif step == "run_fifo":  # {run}/zz is a named pipe
            os.mkfifo(run / "zz")
        elif step == "run_socket":  # {run}/report/zz.png is a unix socket (bound, closed)
            import socket

            (run / "report").mkdir(exist_ok=True)
            with socket.socket(socket.AF_UNIX) as sock:
                sock.bind(str(run / "report" / "zz.png"))
        elif step == "run_user_tmp_folder":  # a user's keep.tmp/x in {run}
            (run / "keep.tmp").mkdir()
            (run / "keep.tmp" / "x").write_text("t")
        elif step == "run_restore_lookalike":  # a user's folder named like a restore one
            (run / ".sensorgap-restore.abcdefgh.tmp").mkdir()
            (run / ".sensorgap-restore.abcdefgh.tmp" / "data.txt").write_text("mine")
        elif step == "hidden_tmp":
            (run / ".x.tmp.xosc").write_text("<half")
        elif step == "edit_first_scenario":
            first = sorted((run / "scenarios").glob("*.xosc"))[0]
            first.write_text(first.read_text() + "<!-- edited -->\n")
        elif step == "unlisted_file":
            (run / "extra.txt").write_text("not listed")
        elif step == "many_ranking_rows":  # row 0 of {run}/ranking.json, 301 times
            data = json.loads((run / "ranking.json").read_text())
            row = data["ranking"][0]
            data["ranking"] = [{**row, "rank": i + 1} for i in range(301)]
            (run / "ranking.json").write_text(json.dumps(data))
        elif step == "duplicate_first_row":  # row 0 of {run}/ranking.json twice
            data = json.loads((run / "ranking.json").read_text())
            data["ranking"].append({**data["ranking"][0], "rank": len(data["ranking"]) + 1})
            (run / "ranking.json").write_text(json.dumps(data))
        elif step.startswith("coverage_map:"):  # {run}/coverage/car_clear, damaged
            _coverage_map(run / "coverage" / "car_clear", step.removeprefix("coverage_map:"))
        elif step.startswith("png_bomb:"):  # {run}/<file>: 10,000 x 10,000 1-bit, 12 kB
            _png_bomb(run / step.removeprefix("png_bomb:"))
        elif step == "many_figures":  # {run}/farfield/eNNN/farfield.png: 501 of them
            for k in range(501):
                (run / "farfield" / f"e{k:03d}").mkdir(parents=True)
                (run / "farfield" / f"e{k:03d}" / "farfield.png").write_bytes(b"\x89PNG")
        elif step.startswith("fifo:"):  # {run}/<file> replaced by a named pipe
            pipe = run / step.removeprefix("fifo:")
            pipe.unlink(missing_ok=True)
            os.mkfifo(pipe)
        elif step.startswith("huge_file:"):  # {run}/<file>: 20,000,001 bytes (sparse)
            huge = run / step.removeprefix("huge_file:")
            huge.parent.mkdir(parents=True, exist_ok=True)
            with huge.open("wb") as f:
                f.write(b"s,pd\n")
                f.truncate(20_000_001)
        elif step == "rename_coverage_map":  # {run}/coverage/car_clear -> truck_fog_50
            (run / "coverage" / "car_clear").rename(run / "coverage" / "truck_fog_50")
        elif step == "job_folder_from_run":  # {out}/system_b: a copy of {run}
            shutil.copytree(run, out / "system_b", symlinks=True)
        elif step == "nearfield_as_out":  # {out}: a copy of {run}/nearfield (certified)
            shutil.copytree(run / "nearfield", out, symlinks=True)
        elif step == "path_max_out":  # {out} in argv: a folder path of 4,070 bytes
            deep = out  # (PATH_MAX 4,096: its folders can be made, its files' names not)
            while len(str(deep)) < 4066 - 251:
                deep = deep / ("d" * 250)
            if len(str(deep)) < 4065:
                deep = deep / ("e" * (4065 - len(str(deep))))
            argv[argv.index(str(out))] = str(deep / "out")
        elif step == "manifest_symlink":
            (folder / "manifest.json").symlink_to("/etc/hostname")
        elif step in ("store_wal", "run_store_wal"):  # {out}'s or {run}'s store in WAL mode
            wal = db if step == "store_wal" else run / "search.sqlite"
            _sql(wal, "PRAGMA journal_mode=wal;")  # closed: no -wal or -shm left
        else:
            raise CaseError(f"unknown setup step {step!r}")
