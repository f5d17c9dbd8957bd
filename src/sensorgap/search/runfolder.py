"""The run folder as a contract: the inputs a search used, recorded, and the one reader of
a run folder (export, report, compare and evaluate rebuild everything from it).

Recording (``record_inputs``, called by ``run_search``): every resolved input file is
copied into ``inputs/`` and listed in ``run.json`` under ``inputs`` with its original
(absolute) path and the SHA-256 of its bytes::

    "inputs": {
      "vehicle":      {"path": "/abs/my_car.toml", "sha256": "...",
                       "copy": "inputs/vehicle/my_car.toml"},
      "environments": {...}, "targets": {...},
      "reaction":     {..., "name": "ads_default"},   # name: null = the file's first model
      "friction":     {...},                          # the [friction] table's file
      "families":     {"<family>": {..., "road": "<road key>"}},
      "roads":        {"<road key>": {...}}
    }

Reading (``open_run``): ``RunFolder`` holds ``ranking.json`` (rows, settings) and
``run.json`` and rebuilds the vehicle, environments, targets, reaction model, friction and
families (on their recorded roads) from the recorded copies, never from a shipped preset of
the same name. A recorded copy whose bytes no longer match its SHA-256 is bad input. When a
recorded original still exists and its SHA-256 differs, one warning line on stderr names it
(the recorded copy is used). A run folder without recorded inputs (older runs, hand-written
rankings) falls back to the shipped presets with a one-line note.
"""

from __future__ import annotations

import hashlib
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from sensorgap.atomic import atomic_write_bytes
from sensorgap.config import EnvironmentConfig, TargetConfig, load_environments, load_targets
from sensorgap.config.load import environments_path
from sensorgap.config.parameters import bound_error
from sensorgap.config.presets import resolve_road, templates_dir
from sensorgap.config.reaction import (
    ReactionConfig,
    friction_source,
    load_friction,
    load_reaction,
    reactions_path,
)
from sensorgap.errors import InputError, say
from sensorgap.filesio import (
    is_temporary,
    loads_json,
    not_a_run_folder,
    previous_json_object,
    regular_file_size,
    write_json,
)
from sensorgap.models import System, load_system
from sensorgap.provenance import sha256_of, versions
from sensorgap.scenarios import load_family
from sensorgap.scenarios.family import Family
from sensorgap.search.evaluate import DetectionRule, Evaluator

INPUTS_DIR = "inputs"
#: Added to the name of an input's copy that would look like a temporary or journal file
COPY_SUFFIX = ".input"
RUN_JSON = "run.json"
RANKING_JSON = "ranking.json"
#: Single-file inputs, in the order ``run.json`` lists them.
SINGLE = ("vehicle", "environments", "targets", "reaction", "friction")
#: Text fields every ranking row must carry.
ROW_TEXT = ("scenario_id", "family", "environment")
#: The classes a ranked row may have (``search.ranking.classify``; only sensor-critical
#: rows are ranked, older runs ranked every class).
ROW_CLASSES = ("sensor-critical", "marginal", "unavoidable", "not critical")
#: What a scenario id may be (it names the exported files).
SCENARIO_ID = re.compile(r"[A-Za-z0-9_-]{1,64}")
#: The search's store of every evaluated candidate (``search.store``): a folder holding
#: one was written by ``sensorgap search``, whose ranked rows carry the store's ids.
STORE_FILE = "search.sqlite"
#: The files a search writes from its ranking (``search.run.ranking_files``), whose
#: SHA-256 its store records.
RANKING_FILES = ("ranking.json", "ranking.csv", "unavoidable.csv", "summary.json")
#: Most rows a ranking holds (``search --top``; ``ranking.json`` rows read by export,
#: report and compare): a report draws each row's figures (~0.5 s a row on a 2-core
#: machine), so the largest ranking stays within a few minutes (docs/limits.md).
MAX_RANKED_ROWS = 300
#: Largest JSON file of a run folder read (ranking.json, run.json, summary.json), bytes: a
#: ranking of MAX_RANKED_ROWS rows is ~1 MB.
MAX_JSON_BYTES = 20_000_000
#: Fields of ``run.json`` a reader checks, and the JSON type each must have.
RUN_INFO_FIELDS: dict[str, type] = {
    "settings": dict,
    "vehicle": str,
    "versions": dict,
    "command": list,
    "config_sha256": dict,
    "inputs": dict,
}

# -- recording -------------------------------------------------------------------------


def reaction_source(reaction: str) -> tuple[Path, str | None]:
    """(file, model name) of a vehicle file's ``reaction`` as ``load_reaction`` resolves
    it: a path -> that file and its first model (None); a name -> the shipped presets."""
    if reaction.endswith(".toml") or "/" in reaction:
        return Path(reaction), None
    return reactions_path(), reaction


class _Recorder:
    """Copies input files into ``folder/inputs`` (each original once, names unique)."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        self.by_path: dict[Path, dict[str, str]] = {}
        self.used: set[str] = set()

    def add(self, sub: str, path: Path, name: str | None = None) -> dict[str, str]:
        src = Path(path).resolve()
        if src in self.by_path:
            return dict(self.by_path[src])
        if not src.is_file():
            raise InputError(src, "", "input file not found (cannot record it in the run folder)")
        data = src.read_bytes()
        # a manifest lists POSIX paths, so a backslash (legal in a POSIX file name) is no
        # part of a copy's name (hostile round fifteen: 'back\slash.toml' was recorded and
        # the run's own verify refused it); run.json's ``copy`` names the copy
        base = (name or src.name).replace("\\", "_")
        # a copy named like a temporary or journal file (``envs.tmp``, ``v-wal``) would
        # make the run's own manifest refuse the folder after the whole search (hostile
        # round 35): such a copy gets ``.input`` added (run.json's ``copy`` names it)
        if is_temporary(base):
            base = f"{base.lstrip('.')}{COPY_SUFFIX}"
        rel = f"{INPUTS_DIR}/{sub}/{base}"
        if rel in self.used:  # another file of the same name
            stem, dot, ext = base.rpartition(".")
            tag = hashlib.sha256(data).hexdigest()[:8]
            rel = f"{INPUTS_DIR}/{sub}/{stem}-{tag}{dot}{ext}" if dot else f"{rel}-{tag}"
        self.used.add(rel)
        atomic_write_bytes(self.folder / rel, data)
        entry = {"path": str(src), "sha256": hashlib.sha256(data).hexdigest(), "copy": rel}
        self.by_path[src] = entry
        return dict(entry)


def record_inputs(
    folder: Path,
    vehicle_file: Path,
    environments_file: Path | None,
    reaction: str,
    families: list[Family],
) -> dict[str, Any]:
    """Copy every input of a search into ``folder/inputs`` and return the ``inputs``
    record of ``run.json`` (see the module docstring). ``reaction``: the vehicle file's
    ``reaction`` setting; each family's road is its resolved ``road`` setting."""
    rec = _Recorder(Path(folder))
    out: dict[str, Any] = {
        "vehicle": rec.add("vehicle", vehicle_file),
        "environments": rec.add("environments", environments_file or environments_path()),
        "targets": rec.add("targets", templates_dir() / "targets.toml"),
    }
    r_path, r_name = reaction_source(reaction)
    out["reaction"] = {**rec.add("reaction", r_path), "name": r_name}
    out["friction"] = rec.add("reaction", friction_source(reaction))
    fams: dict[str, Any] = {}
    roads: dict[str, Any] = {}
    for f in families:
        road = rec.add("roads", resolve_road(str(f.settings["road"])))
        key = Path(road["copy"]).stem
        roads[key] = road
        fams[f.name] = {**rec.add("families", Path(f.source), f"{f.name}.toml"), "road": key}
    out["families"] = fams
    out["roads"] = roads
    return out


def write_search_record(
    folder: Path, vehicle_ref: str, settings: dict[str, Any], inputs: dict[str, Any]
) -> dict[str, Any]:
    """``folder/run.json`` after a search: the vehicle, settings, versions and the recorded
    inputs; other fields of an existing ``run.json`` (``sensorgap run``'s command and
    config hashes) are kept."""
    path = Path(folder) / RUN_JSON
    info = previous_json_object(path)  # {} when absent or damaged
    kept = info.get("settings")
    info.update(
        {
            "vehicle": vehicle_ref,
            "settings": {**(kept if isinstance(kept, dict) else {}), **settings},
            "versions": versions(),
            "inputs": inputs,
        }
    )
    write_json(path, info)
    return info


def copy_record(src: Path, dst: Path) -> set[str]:
    """Copy ``run.json`` and the recorded inputs of run folder ``src`` into ``dst`` (a
    catalog exported elsewhere keeps the inputs it was built from); returns the relative
    POSIX paths of the inputs copied."""
    src, dst = Path(src), Path(dst)
    info = read_run_info(src)
    copied: set[str] = set()
    if not isinstance(info.get("inputs"), dict):
        return copied
    for _, e in _entries(info["inputs"]):
        rel = str(e.get("copy", ""))
        if rel and (src / rel).is_file() and ".." not in Path(rel).parts:
            atomic_write_bytes(dst / rel, (src / rel).read_bytes())
            copied.add(Path(rel).as_posix())
    atomic_write_bytes(dst / RUN_JSON, (src / RUN_JSON).read_bytes())
    return copied


# -- reading ---------------------------------------------------------------------------


def _check_size(path: Path) -> None:
    try:
        regular_file_size(path, MAX_JSON_BYTES)
    except OSError:
        return  # reported by the read itself


def read_json_file(path: Path) -> Any:
    """A JSON file of a run folder (``InputError`` naming it when unreadable or larger
    than ``MAX_JSON_BYTES``)."""
    _check_size(Path(path))
    try:
        return loads_json(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise InputError(path, "", f"unreadable JSON: {exc}") from None
    except RecursionError:
        raise InputError(path, "", "unreadable JSON: nested too deeply") from None


def read_run_info(folder: Path) -> dict[str, Any]:
    """``run.json`` of a run folder ({} when absent), its fields checked
    (``RUN_INFO_FIELDS``): anything else -> ``InputError`` naming the file and field."""
    path = Path(folder) / RUN_JSON
    if not path.is_file():
        return {}
    info = read_json_file(path)
    if not isinstance(info, dict):
        raise InputError(path, "", "expected a JSON object")
    for key, kind in RUN_INFO_FIELDS.items():
        if key in info and not isinstance(info[key], kind):
            want = "object" if kind is dict else "array" if kind is list else "string"
            raise InputError(path, key, f"expected a JSON {want}, got {type(info[key]).__name__}")
    if not all(isinstance(c, str) for c in info.get("command", [])):
        raise InputError(path, "command", "expected an array of strings")
    for key in ("versions", "config_sha256"):
        if not all(isinstance(v, str | int | float) for v in info.get(key, {}).values()):
            raise InputError(path, key, "expected an object of names to strings")
    return info


def _read_ranking(folder: Path) -> tuple[list[dict[str, Any]], dict[str, Any], dict[str, Any], str]:
    """(rows, settings, the whole file, vehicle as given) of ``ranking.json``, checked."""
    path = folder / RANKING_JSON
    if not path.is_file():
        raise InputError(
            path,
            "",
            "not a search run folder (ranking.json is missing); run "
            "`sensorgap search --out DIR` first",
        )
    _check_size(path)
    try:
        data = loads_json(path.read_text(encoding="utf-8"))
    except (ValueError, RecursionError) as exc:
        raise InputError(path, "", f"malformed ranking file: not JSON ({exc})") from None
    if not isinstance(data, dict):
        raise InputError(path, "", "malformed ranking file: expected a JSON object")
    rows, settings = data.get("ranking"), data.get("settings")
    if not isinstance(rows, list):
        raise InputError(path, "ranking", "malformed ranking file: expected a list of rows")
    if len(rows) > MAX_RANKED_ROWS:
        raise InputError(
            path, "ranking", f"{len(rows)} rows; at most {MAX_RANKED_ROWS} (search --top) allowed"
        )
    if not isinstance(settings, dict):
        raise InputError(path, "settings", "malformed ranking file: expected an object")
    vehicle = settings.get("vehicle_ref") or settings.get("vehicle_file")
    if not isinstance(vehicle, str) or not vehicle:
        raise InputError(
            path,
            "settings.vehicle_ref",
            "malformed ranking file: expected the vehicle (a preset name or a path)",
        )
    if not settings.get("vehicle_ref"):
        vehicle = Path(vehicle).stem
    envs = settings.get("environments", [])
    if not (isinstance(envs, list) and all(isinstance(e, str) for e in envs)):
        raise InputError(
            path,
            "settings.environments",
            "malformed ranking file: expected a list of environment names",
        )
    seen: dict[str, int] = {}
    for i, row in enumerate(rows):
        if not isinstance(row, dict):
            raise InputError(path, f"ranking[{i}]", "malformed ranking file: expected an object")
        for key in ROW_TEXT:
            if not isinstance(row.get(key), str) or not row[key]:
                raise InputError(
                    path, f"ranking[{i}].{key}", "malformed ranking file: missing or not a string"
                )
        if "class" in row and row["class"] not in ROW_CLASSES:
            raise InputError(
                path,
                f"ranking[{i}].class",
                "malformed ranking file: expected "
                f"one of {', '.join(ROW_CLASSES)}, got {str(row['class'])[:40]!r}",
            )
        if not SCENARIO_ID.fullmatch(row["scenario_id"]):
            # it names files (scenarios/<id>.xosc): no path separators, no markup
            raise InputError(
                path,
                f"ranking[{i}].scenario_id",
                "malformed ranking file: "
                "expected 1-64 letters, digits, '_' or '-', got "
                f"{row['scenario_id'][:80]!r}",
            )
        rank = row.get("rank")
        if not isinstance(rank, int) or isinstance(rank, bool) or not 1 <= rank <= MAX_RANKED_ROWS:
            raise InputError(
                path,
                f"ranking[{i}].rank",
                f"malformed ranking file: expected a positive integer (1..{MAX_RANKED_ROWS}), "
                f"got {str(rank)[:40]!r}",
            )
        if row["scenario_id"] in seen:  # one catalog file per id: the second overwrote it
            raise InputError(
                path,
                f"ranking[{i}].scenario_id",
                f"malformed ranking file: {row['scenario_id']!r} is also ranking"
                f"[{seen[row['scenario_id']]}]",
            )
        seen[row["scenario_id"]] = i
        found = row.get("found_by_seeds")
        if found is not None and (
            not isinstance(found, int) or isinstance(found, bool) or not 0 <= found <= 10
        ):
            raise InputError(
                path,
                f"ranking[{i}].found_by_seeds",
                "malformed ranking file: expected empty or an integer 0..10, got "
                f"{str(found)[:40]!r}",
            )
        _finite_row(path, i, row)
    return rows, settings, data, vehicle


def _finite_row(path: Path, i: int, row: dict[str, Any]) -> None:
    """Every number of a ranking row finite (a search writes null for none), and each
    parameter (``p_*``) and sun angle a finite number or, for a choice, a name: "nan" or
    "inf" is refused here, before anything is rebuilt or exported from it."""
    for key, v in row.items():
        bad = isinstance(v, float) and not math.isfinite(v)
        if isinstance(v, str) and (key.startswith("p_") or key.startswith("sun_")):
            try:
                bad = not math.isfinite(float(v))
            except ValueError:
                bad = key.startswith("sun_")  # a choice name is text; a sun angle is not
        if bad:
            raise InputError(
                path,
                f"ranking[{i}].{key[:64]}",
                f"malformed ranking file: expected a finite number, got {str(v)[:40]!r}",
            )
        why = (
            bound_error(key[2:], float(v))
            if key.startswith("p_") and isinstance(v, int | float) and not isinstance(v, bool)
            else None
        )
        if why:  # a physical bound (config.parameters)
            raise InputError(path, f"ranking[{i}].{key[:64]}", why)


@dataclass
class RunFolder:
    """A run folder: its ranking (rows, settings), ``run.json`` and recorded inputs."""

    folder: Path
    rows: list[dict[str, Any]]
    settings: dict[str, Any]
    info: dict[str, Any]
    #: the vehicle as the search was given it (preset name or absolute path)
    vehicle_ref: str
    #: ``ranking.json`` as a whole ({} without a ranking)
    data: dict[str, Any] = field(default_factory=dict)
    _cache: dict[str, Any] = field(default_factory=dict, repr=False)

    @property
    def vehicle(self) -> str:
        """Alias of ``vehicle_ref`` (the vehicle as given to the search)."""
        return self.vehicle_ref

    @property
    def searched(self) -> bool:
        """True when the folder holds the search's store (``STORE_FILE``): its ranked rows
        are search results, each ``scenario_id`` the store's id of the row's candidate."""
        return (self.folder / STORE_FILE).is_file()

    @property
    def recorded(self) -> bool:
        """True when ``run.json`` records the run's inputs."""
        return isinstance(self.info.get("inputs"), dict)

    def _entry(self, *keys: str) -> dict[str, Any] | None:
        node: Any = self.info.get("inputs")
        for k in keys:
            if not isinstance(node, dict):
                return None
            node = node.get(k)
        return node if isinstance(node, dict) else None

    def input_path(self, *keys: str) -> Path | None:
        """The recorded copy of an input (``"vehicle"``, ``"families", name``, ...), or
        None when the run does not record it."""
        e = self._entry(*keys)
        return None if e is None else self.folder / str(e["copy"])

    def _cached(self, key: str, make: Any) -> Any:
        if key not in self._cache:
            self._cache[key] = make()
        return self._cache[key]

    def system(self) -> System:
        """The vehicle: the recorded copy, else the vehicle as given; a folder recording
        neither (a job's top folder, any other folder) -> ``InputError`` naming it (it was
        taken for an empty ``--vehicle``: hostile round 25)."""
        p = self.input_path("vehicle")
        if p is None and not self.vehicle_ref:
            raise InputError(
                self.folder,
                "",
                "neither run.json nor ranking.json says which vehicle this run is for "
                "(a job's folder holds one run folder per vehicle: name that one)",
            )
        # a recorded copy's reaction model is recorded apart (its path may be relative)
        check = self._entry("reaction") is None
        return self._cached(
            "system",
            lambda: load_system(p if p is not None else self.vehicle_ref, check_reaction=check),
        )

    def environments(self) -> dict[str, EnvironmentConfig]:
        """Every environment of the run's environments file (recorded copy, else the
        shipped presets)."""
        p = self.input_path("environments")
        return self._cached("envs", lambda: load_environments(p))

    def targets(self) -> dict[str, TargetConfig]:
        """The target classes (recorded copy, else the shipped ``targets.toml``)."""
        p = self.input_path("targets")
        return self._cached("targets", lambda: load_targets(p))

    def reaction(self) -> ReactionConfig:
        """The reaction model the search used (recorded copy, else as the vehicle file
        names it)."""
        e = self._entry("reaction")
        if e is None:
            return self._cached("reaction", lambda: load_reaction(self.system().config.reaction))
        copy = self.folder / str(e["copy"])
        name = e.get("name")
        return self._cached(
            "reaction",
            lambda: load_reaction(copy) if name is None else load_reaction(str(name), presets=copy),
        )

    def friction(self) -> dict[str, float]:
        """Peak road friction per condition (recorded copy, else the shipped presets)."""
        p = self.input_path("friction")
        return self._cached("friction", lambda: load_friction(p))

    def family(self, name_or_path: str) -> Family:
        """A family of the run: the recorded copy on its recorded road; a name the run
        did not record is ``InputError`` (never the shipped preset of that name); a path,
        or any name in a run without a record, is loaded as given."""
        e = self._entry("families", name_or_path)
        recorded = self._entry("families") if self.recorded else None
        is_path = name_or_path.endswith(".toml") or "/" in name_or_path
        if e is None and recorded is not None and not is_path:
            # a name the run did not search: never the shipped preset of that name
            raise InputError(
                self.folder / RUN_JSON,
                "inputs.families",
                f"no family {name_or_path[:64]!r} in this run; it searched "
                f"{', '.join(sorted(recorded)) or 'none'}",
            )
        targets = self.input_path("targets")
        if e is None:
            return self._cached(
                f"family {name_or_path}", lambda: load_family(name_or_path, targets=targets)
            )
        road = self.input_path("roads", str(e.get("road")))
        if road is None:  # never the shipped road its file names (hostile round 24)
            roads = self._entry("roads")
            raise InputError(
                self.folder / RUN_JSON,
                f"inputs.families.{name_or_path[:64]}.road",
                f"{str(e.get('road'))[:64]!r} names no road the run recorded "
                f"({', '.join(sorted(roads)) if isinstance(roads, dict) and roads else 'none'})",
            )
        copy = self.folder / str(e["copy"])
        return self._cached(
            f"family {name_or_path}", lambda: load_family(str(copy), road=road, targets=targets)
        )

    def evaluator(
        self, mode: str = "exact", rule: DetectionRule | None = None, system: System | None = None
    ) -> Evaluator:
        """An evaluator of the run's vehicle (or ``system``: a variant of it) with its
        recorded reaction model, friction and target classes."""
        ev = Evaluator(
            system if system is not None else self.system(),
            mode=mode,
            rule=rule,
            reaction=self.reaction(),
            friction=self.friction(),
        )
        ev._targets.update(self.targets())  # the cache Evaluator.target fills from presets
        recorded = self.input_path("targets")
        if recorded is not None:  # a class the recorded copy lacks is refused
            ev.targets_source = str(recorded)
        return ev

    def check_inputs(self, warn: bool = True) -> None:
        """Verify the recorded copies against their SHA-256 (a modified copy is bad
        input) and, ``warn``, warn, one line, about originals changed since the run."""
        inputs = self.info.get("inputs")
        if not isinstance(inputs, dict):
            return
        changed = []
        try:
            entries = _entries(inputs)
        except ValueError as exc:
            raise InputError(self.folder / RUN_JSON, "inputs", str(exc)) from None
        # a search records every single-file input it used: without its entry a reader
        # would take today's preset of that name instead (hostile round sixteen)
        lost = [k for k in SINGLE if k not in inputs]
        if lost:
            raise InputError(
                self.folder / RUN_JSON,
                f"inputs.{lost[0]}",
                f"missing: the run recorded its inputs ({', '.join(SINGLE)}), and without "
                "this entry today's preset would stand in for the copy it used; restore "
                f"{RUN_JSON} or search again",
            )
        for label, e in entries:
            if not all(isinstance(e.get(k), str) for k in ("path", "sha256", "copy")):
                raise InputError(
                    self.folder / RUN_JSON,
                    f"inputs.{label}",
                    "expected path, sha256 and copy (strings)",
                )
            copy = self.folder / e["copy"]
            if ".." in Path(e["copy"]).parts or Path(e["copy"]).is_absolute():
                raise InputError(
                    self.folder / RUN_JSON,
                    f"inputs.{label}.copy",
                    "must be a path inside the run folder",
                )
            if not copy.is_file():
                raise InputError(
                    copy, "", f"recorded input ({label}) is missing from the run folder"
                )
            if sha256_of(copy) != e["sha256"]:
                raise InputError(
                    copy,
                    "",
                    f"recorded input ({label}) was modified: its SHA-256 differs from run.json",
                )
            orig = Path(e["path"])
            if (
                orig.is_file()
                and orig.resolve() != copy.resolve()
                and sha256_of(orig) != e["sha256"]
            ):
                changed.append(f"{label} {orig}")
        if changed and warn:
            say(
                f"warning: {self.folder}: input changed since the run: "
                + "; ".join(changed)
                + " (SHA-256 differs; using the recorded copy)"
            )

    def check_store(self) -> None:
        """In a folder the search wrote (``searched``: it holds ``STORE_FILE``), what
        ``run.json`` and ``ranking.json`` say the search used must be what its store
        recorded (``store.read_meta``: the settings and the digests of every input): the
        recorded inputs (vehicle, families and their roads by SHA-256; environments,
        target classes, reaction model and friction by the digests of what they load),
        ``run.json``'s ``inputs.reaction.name`` and the settings export and report read
        (detection, environments, families, ...). A mismatch is ``InputError`` naming the
        file and field: ``run.json`` and ``manifest.json`` edited together (every entry
        re-hashed) rebuilt the run with another reaction model, and the report explained
        its scenarios by a model the search never used. The store is read without
        writing anything (a WAL database refused first, ``store.refuse_wal``)."""
        from sensorgap.search.store import (
            OUTPUTS_KEY,
            RANKED_KEY,
            configs_digest,
            reaction_digest,
            read_meta,
        )

        meta = read_meta(self.folder / STORE_FILE)
        stored: dict[str, Any] = meta.get("settings", {})
        digests: dict[str, Any] = meta.get("inputs", {})
        run_json = self.folder / RUN_JSON

        def refuse(path: Path, field: str, what: str, want: str) -> InputError:
            return InputError(
                path,
                field,
                f"{what} does not match the run's {STORE_FILE} ({want}, as searched); "
                f"restore {path.name} or search again",
            )

        if self.data:  # ranking.json's settings: what export and report read
            for key, want in stored.items():
                if self.settings.get(key) != want:
                    raise refuse(
                        self.folder / RANKING_JSON,
                        f"settings.{key}",
                        f"{str(self.settings.get(key))[:80]!r}",
                        f"{str(want)[:80]!r}",
                    )
        if self.data:  # a search that ranked recorded all of these with its ranking
            for key in ("settings", "inputs", RANKED_KEY, OUTPUTS_KEY):
                if key not in meta:
                    raise InputError(
                        self.folder / STORE_FILE,
                        f"meta.{key}",
                        "missing: a search records it with its ranking (the store was "
                        "changed after the search, or another tool wrote it); restore the "
                        "store or search again",
                    )
            # and each holds what every search records in it: an emptied row ('{}')
            # switched the input checks off (hostile round twenty-one, F3)
            wanted = [("settings", k) for k in sorted(self.settings)]
            wanted += [("inputs", k) for k in ("vehicle", "reaction", "environments", "targets")]
            for row, key in wanted:
                if key not in meta[row]:
                    raise InputError(
                        self.folder / STORE_FILE,
                        f"meta.{row}.{key}",
                        "missing: a search records it (the store was changed after the "
                        "search, or another tool wrote it); restore the store or search "
                        "again",
                    )
            if not any(str(k).startswith("family ") for k in meta["inputs"]):
                raise InputError(
                    self.folder / STORE_FILE,
                    "meta.inputs",
                    "records no family file: a search records each (the store was changed "
                    "after the search, or another tool wrote it); restore the store or "
                    "search again",
                )
        self._check_ranked_files(meta.get(OUTPUTS_KEY))
        self._check_ranked_numbers(meta.get(RANKED_KEY))
        given = self.info.get("settings", {})
        for key, want in stored.items():  # run.json's (sensorgap run's: a part of them)
            if key in given and _normal_setting(key, given[key]) != want:
                raise refuse(
                    run_json,
                    f"settings.{key}",
                    f"{str(given[key])[:80]!r}",
                    f"{str(want)[:80]!r}",
                )
        inputs = self.info.get("inputs", {})
        if "reaction" in stored and "reaction" in inputs:
            label = self.reaction().label()
            if label != stored["reaction"]:
                name, _, now = label.partition(":")
                then_name, _, then = str(stored["reaction"]).partition(":")
                if name != then_name:
                    raise refuse(
                        run_json,
                        "inputs.reaction.name",
                        f"the reaction model {name!r}",
                        f"{then_name!r}",
                    )
                # the same model with other settings (hostile round 39: the line said the
                # names differed and showed the same name twice)
                raise refuse(
                    run_json,
                    "inputs.reaction",
                    f"the settings of reaction model {name!r} in its recorded copy "
                    f"({now.strip()[:160]})",
                    then.strip()[:160],
                )
        fams = inputs.get("families", {})
        names = sorted(k[len("family ") :] for k in digests if k.startswith("family "))
        if "families" in inputs and names and sorted(fams) != names:
            raise refuse(
                run_json,
                "inputs.families",
                f"{', '.join(sorted(fams)) or 'none'}",
                ", ".join(names),
            )
        checks: list[tuple[str, str, Any]] = []  # (store key, run.json field, what it gives)
        if "vehicle" in inputs:
            checks.append(("vehicle", "inputs.vehicle", lambda: inputs["vehicle"]["sha256"]))
        for n in names if "families" in inputs else []:
            roads = inputs.get("roads", {})
            road = roads.get(str(fams[n].get("road")), {})
            checks.append((f"family {n}", f"inputs.families.{n}", lambda n=n: fams[n]["sha256"]))
            checks.append(
                (f"road of {n}", f"inputs.families.{n}.road", lambda r=road: r.get("sha256"))
            )
        if "environments" in inputs and isinstance(stored.get("environments"), list):
            envs = self.environments()
            chosen = [e for e in stored["environments"] if isinstance(e, str)]
            checks.append(
                (
                    "environments",
                    "inputs.environments",
                    lambda: configs_digest({e: envs[e] for e in chosen if e in envs}),
                )
            )
        if "targets" in inputs:
            checks.append(("targets", "inputs.targets", lambda: configs_digest(self.targets())))
        if "reaction" in inputs:
            checks.append(
                (
                    "reaction",
                    "inputs.friction" if "friction" in inputs else "inputs.reaction",
                    lambda: reaction_digest(self.reaction(), self.friction()),
                )
            )
        for key, label, given_digest in checks:
            if key in digests and given_digest() != digests[key]:
                whole = label.startswith(("inputs.vehicle", "inputs.families"))
                what = "the recorded file" if whole else "what it loads"
                raise refuse(run_json, label, what, "another SHA-256")

    def stored_ids(self) -> frozenset[str] | None:
        """The ``scenario_id`` values of the ranking's rows that are candidates of the
        run's store (``check_store``; None before it ran or without a store)."""
        ids: frozenset[str] | None = self._cache.get("stored_ids")
        return ids

    def _check_ranked_files(self, recorded: dict[str, Any] | None) -> None:
        """Each ranking file the search wrote (``ranking.json``, ``ranking.csv``,
        ``unavoidable.csv``, ``summary.json``) is, byte for byte, what the store recorded
        (``store.record_ranked``; a store of a ranked search without the record is refused
        by ``check_store``: hostile round twenty, F2). Else ``InputError`` naming the
        file: rows removed or re-ranked in
        ``ranking.json``, or ``summary.json``'s best P(collision) edited, with the
        manifest re-hashed, were reported, exported and compared as the search's
        (hostile round eighteen, F5: the report's top weakness was the second one)."""
        if recorded is None:
            return
        missing = [
            n
            for n in RANKING_FILES
            if not (isinstance(recorded, dict) and isinstance(recorded.get(n), str))
        ]
        if missing:  # the search writes all four: a partial record is not an older one
            raise InputError(
                self.folder / STORE_FILE,
                "meta.ranking_files",
                f"the record of the ranking files lacks {missing[0]}'s SHA-256 (a search "
                f"records all of {', '.join(RANKING_FILES)}); restore the store or search "
                "again",
            )
        assert isinstance(recorded, dict)
        for name in RANKING_FILES:  # only these names (a store's own are not followed)
            digest = recorded[name]
            path = self.folder / name
            if path.is_file() and sha256_of(path) != digest:
                raise InputError(
                    path,
                    "",
                    f"is not the file the search wrote (its SHA-256 is not the one the "
                    f"run's {STORE_FILE} recorded): changed after the search; restore it "
                    "or search again",
                )

    def _check_ranked_numbers(self, ranked: dict[str, Any] | None) -> None:
        """Every number a ranked (or unavoidable) row of ``ranking.json`` states must be
        what the store recorded for that row's ``scenario_id``: the metrics (collision
        probability, impact speed, Pd, confirmation and detection times, risk, ...) as
        exact evaluation gave them (``store.record_ranked``; a ranked search's store
        without the record is refused by ``check_store``), and
        ``lookup_collision_probability`` as the
        search's lookup gave it (its ``candidates`` row). Equal as written (JSON floats
        round-trip; times rounded as ``metrics.output_value`` writes them). A mismatch is
        ``InputError`` naming ``ranking.json`` and the row's field: a ranking edited
        with its manifest re-hashed was reported (and exported, compared) as exact."""
        from sensorgap.search.metrics import check_metric_value, output_value
        from sensorgap.search.store import read_results

        path = self.folder / RANKING_JSON
        groups = [
            (name, rows)
            for name in ("ranking", "unavoidable")
            if isinstance(rows := self.data.get(name), list)
        ]
        ids = [
            str(row.get("scenario_id"))
            for _, rows in groups
            for row in rows
            if isinstance(row, dict)
        ]
        lookup = read_results(self.folder / STORE_FILE, ids)
        self._cache["stored_ids"] = frozenset(lookup)

        def refuse(field: str, given: Any, want: Any) -> InputError:
            return InputError(
                path,
                field,
                f"{str(given)[:80]} does not match the run's {STORE_FILE} "
                f"({str(want)[:80]}, as searched); restore {path.name} or search again",
            )

        for name, rows in groups:
            for i, row in enumerate(rows):
                if not isinstance(row, dict):
                    continue
                sid = str(row.get("scenario_id"))
                where = f"{name}[{i}]"
                if sid not in lookup:  # refused as its row is read (export.spec): the
                    continue  # id its parameters give, or no stored candidate
                given = row.get("lookup_collision_probability")
                want = lookup[sid].get("collision_probability")
                if given is not None and given != want:
                    raise refuse(f"{where}.lookup_collision_probability", given, want)
                if not isinstance(ranked, dict):
                    continue
                exact = ranked.get(sid)
                if not isinstance(exact, dict):
                    raise InputError(
                        path,
                        f"{where}.scenario_id",
                        f"{sid[:80]!r} is not a ranked candidate of the run's {STORE_FILE}; "
                        f"restore {path.name} or search again",
                    )
                for metric, value in exact.items():
                    if metric not in row or not isinstance(value, int | float):
                        continue
                    try:  # a value no search writes: refused as its row is read
                        check_metric_value(metric, row[metric])
                    except ValueError:
                        continue
                    want = output_value(metric, float(value))
                    if row[metric] != want or isinstance(row[metric], bool):
                        raise refuse(f"{where}.{metric}", row[metric], want)


def _normal_setting(key: str, value: Any) -> Any:
    """A setting of ``run.json`` as the search records it (``sensorgap run`` writes its
    own: environments as given, with repeats; families as given, a file by its path)."""
    if key == "environments" and isinstance(value, list):
        return list(dict.fromkeys(value))
    if key == "families" and isinstance(value, list):
        return [
            Path(v).stem if isinstance(v, str) and (v.endswith(".toml") or "/" in v) else v
            for v in value
        ]
    return value


def _entries(inputs: dict[str, Any]) -> list[tuple[str, dict[str, Any]]]:
    """Every recorded input of ``run.json``'s ``inputs`` as (label, entry); an entry that
    is not an object (or a group that is not an object of them) is ``ValueError``, so a
    damaged record is refused instead of falling back to the shipped presets."""
    out = []
    for k in SINGLE:
        if k in inputs:
            if not isinstance(inputs[k], dict):
                raise ValueError(f"{k}: expected an object (path, sha256, copy)")
            out.append((k, inputs[k]))
    for group in ("families", "roads"):
        sub = inputs.get(group, {})
        if not isinstance(sub, dict):
            raise ValueError(f"{group}: expected an object of names to entries")
        for n, e in sub.items():
            if not isinstance(e, dict):
                raise ValueError(f"{group}.{str(n)[:64]}: expected an object (path, sha256, copy)")
            out.append((f"{group}.{n}", e))
    return out


def open_run(folder: Path, ranking: bool = True, warn: bool = True) -> RunFolder:
    """Read a run folder (see the module docstring). ``ranking``: ``ranking.json`` is
    required (else a folder without it reads as one with no ranked scenarios). ``warn``:
    one line about recorded originals changed since the run. Bad input -> ``InputError``
    naming the file and field."""
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(
            folder,
            "",
            not_a_run_folder(folder)
            + (" (ranking.json is missing)" if ranking and not folder.exists() else ""),
        )
    info = read_run_info(folder)
    rows: list[dict[str, Any]] = []
    settings: dict[str, Any] = {}
    data: dict[str, Any] = {}
    vehicle = str(info.get("vehicle", ""))
    if ranking or (folder / RANKING_JSON).is_file():
        rows, settings, data, vehicle = _read_ranking(folder)
    run = RunFolder(folder, rows, settings, info, vehicle, data)
    if run.recorded:
        run.check_inputs(warn)
        if run.searched:  # run.json and ranking.json as the search's store recorded them
            run.check_store()
    elif rows:  # rebuilding from presets of the same names could silently differ
        raise InputError(
            folder / RUN_JSON,
            "inputs",
            "missing: the run does not record "
            "its inputs (run.json absent, or from an older sensorgap that did not "
            "keep them), so its scenarios cannot be rebuilt as searched; run "
            "the search again",
        )
    return run


#: The first bytes of every SQLite database file (its header string).
SQLITE_HEADER = b"SQLite format 3\x00"


def _is_search_run(folder: Path) -> bool:
    """Whether ``folder`` is a search's run folder: ``run.json`` beside the search's store,
    an SQLite database (its header). A ``run.json`` alone, or beside a ``ranking.json``
    or a ``search.sqlite`` that is no database, may be a user's files (hostile rounds 41
    and 42, F1 and F5: ``nearfield --out U`` certified ``U/notes/run.json`` beside a
    ``ranking.json`` of the user's, and ``verify U`` then read them as a run)."""
    if not (folder / RUN_JSON).is_file():
        return False
    try:
        with (folder / STORE_FILE).open("rb") as f:
            return f.read(len(SQLITE_HEADER)) == SQLITE_HEADER
    except OSError:
        return False


def search_runs(folder: Path) -> list[Path]:
    """The search runs of ``folder`` (``_is_search_run``): itself, and for a job's OUT each
    vehicle folder directly below it."""
    runs = [folder] if _is_search_run(folder) else []
    try:
        below = sorted(os.scandir(folder), key=lambda e: e.name)
    except OSError:
        below = []
    for entry in below:
        if entry.is_dir(follow_symlinks=False) and _is_search_run(Path(entry.path)):
            runs.append(Path(entry.path))
    return runs


def check_recorded(folder: Path) -> None:
    """The search runs of ``folder`` (``search_runs``) read as ``export`` and ``report``
    read them (``open_run``, no warning about changed originals): every recorded copy
    matching the SHA-256 ``run.json`` gives it, ``run.json`` and ``ranking.json`` what the
    search's store recorded. ``verify`` checks this after the manifest: a copy edited with
    the manifest re-hashed passed ``verify`` and was refused by ``report`` (remark of
    session 26). ``InputError`` naming the file and field."""
    for run in search_runs(folder):
        open_run(run, ranking=False, warn=False)


def read_run(folder: Path) -> RunFolder:
    """A search run folder with its ranking (``open_run(folder, ranking=True)``)."""
    return open_run(folder, ranking=True)
