"""``sensorgap report --run DIR``: the audit report of one vehicle's run folder.

Reads what the pipeline wrote (``run.json``, coverage, near field, far field, ranking,
summary, catalog) and writes ``DIR/report.html`` (one self-contained file) and
``DIR/report.md`` (same content, PNGs in ``DIR/report/``): the summary page first
(``report.summary``), then the detailed sections, the sensor and parameter-source tables in
an appendix at the end. A part of the pipeline that was not run gives a
one-line "not part of this run"; a file that is present but unreadable is bad input
(``InputError`` naming it). The only non-deterministic field is the generation time
(``SOURCE_DATE_EPOCH`` fixes it).
"""

from __future__ import annotations

import csv
import json
import math
import os
from pathlib import Path
from typing import Any

from sensorgap.atomic import atomic_write_text
from sensorgap.config.presets import templates_dir
from sensorgap.coverage.outputs import read_coverage_npz
from sensorgap.errors import InputError, cut_quoted, shell_join
from sensorgap.export.simulate import read_catalog_index
from sensorgap.export.spec import ScenarioSpec
from sensorgap.filesio import not_a_run_folder, regular_file_size
from sensorgap.models import System
from sensorgap.provenance import utc_now, versions
from sensorgap.report.anchors import anchors_section
from sensorgap.report.document import (
    NOT_RUN,
    Block,
    Image,
    Links,
    Para,
    Section,
    Table,
    embedded_png,
    render_html,
    render_markdown,
)
from sensorgap.report.figures import scenario_figure, scenario_trace
from sensorgap.report.summary import (
    KMH,
    RankedScenario,
    explain_spec,
    robustness_section,
    summary_section,
    weakness_sentence,
)
from sensorgap.search.evaluate import MAP_RESOLUTION_M, DetectionRule
from sensorgap.search.metrics import metric_names
from sensorgap.search.possible import MAX_INFEASIBLE_KINDS, MAX_KIND_CHARS, START_TTC_S
from sensorgap.search.ranking import named_step
from sensorgap.search.robustness import ROBUSTNESS_TOP, finding_robustness
from sensorgap.search.runfolder import STORE_FILE, RunFolder, open_run, read_json_file

REPORT_DIR = "report"
#: What a report writes into a run folder (``filesio.refuse_if_changed``).
REPORT_WRITES = ("report.html", "report.md", f"{REPORT_DIR}/")


def read_json(path: Path) -> Any:
    """A JSON file of the run folder (``InputError`` naming it when unreadable or larger
    than ``search.runfolder.MAX_JSON_BYTES``)."""
    return read_json_file(path)


def _object(path: Path, data: Any, field: str = "", key: str | None = None) -> dict[str, Any]:
    """``data`` (or ``data[key]``, {} when absent) as a JSON object; anything else ->
    ``InputError`` naming the file and the field."""
    if key is not None:
        field = f"{field}.{key}" if field else key
        data = data.get(key, {})
    if not isinstance(data, dict):
        raise InputError(path, field, f"expected a JSON object, got {type(data).__name__}")
    return data


def _check_stability(path: Path, stab: dict[str, Any]) -> None:
    """The ``stability`` block of a search's summary.json (``search.run``): ``seeds`` an
    integer 1..10, ``found_by`` / ``found_near_by`` / ``budget_per_seed`` lists of
    non-negative integers, ``top`` a positive integer, ``near_distance`` a finite number
    >= 0; anything else -> ``InputError`` naming the field."""

    def whole(v: Any) -> bool:
        return isinstance(v, int) and not isinstance(v, bool)

    seeds = stab.get("seeds", 1)
    if not whole(seeds) or not 1 <= seeds <= 10:
        raise InputError(path, "stability.seeds", f"expected an integer 1..10, got {seeds!r:.40}")
    for key in ("found_by", "found_near_by", "budget_per_seed"):
        v = stab.get(key, [])
        if not isinstance(v, list) or not all(whole(x) and x >= 0 for x in v):
            raise InputError(
                path, f"stability.{key}", f"expected a list of non-negative integers, got {v!r:.60}"
            )
    top = stab.get("top", 10)
    if not whole(top) or top < 1:
        raise InputError(path, "stability.top", f"expected a positive integer, got {top!r:.40}")
    d = stab.get("near_distance", 0.15)
    if not isinstance(d, int | float) or isinstance(d, bool) or not 0.0 <= d < float("inf"):
        raise InputError(
            path, "stability.near_distance", f"expected a finite number >= 0, got {d!r:.40}"
        )


def _numbers(
    path: Path,
    data: dict[str, Any],
    field: str,
    keys: tuple[str, ...],
    required: tuple[str, ...] = (),
    at_least: float | None = None,
) -> None:
    """Each of ``keys`` in ``data`` a finite number (or null), ``>= at_least`` when given
    (an area, a length: a negative one was printed); ``required`` ones present (a NaN area
    was printed as "nan m2")."""
    for k in keys:
        v = data.get(k)
        if (v is None and k in required) or (
            v is not None and (isinstance(v, bool) or not isinstance(v, int | float))
        ):
            raise InputError(
                path, f"{field}.{k}" if field else k, f"expected a number, got {v!r:.40}"
            )
        if v is not None and not math.isfinite(v):
            raise InputError(
                path, f"{field}.{k}" if field else k, f"expected a number, got {v!r} (not finite)"
            )
        if v is not None and at_least is not None and v < at_least:
            raise InputError(
                path,
                f"{field}.{k}" if field else k,
                f"expected a number >= {at_least:g}, got {v!r}",
            )


def _check_search_summary(path: Path, search: dict[str, Any]) -> None:
    """The fields of a search's summary.json the report prints: counts (``candidates``,
    ``feasible``, ``infeasible``, per family and of ``lookup_vs_exact``) non-negative
    integers, ``best_collision_probability`` within 0..1, ``best_log10_risk`` finite,
    ``settings`` and ``lookup_vs_exact`` objects; anything else -> ``InputError`` naming the
    field (a NaN count was an internal error, a text probability was printed as it was)."""

    def count(data: dict[str, Any], field: str, keys: tuple[str, ...]) -> None:
        for k in keys:
            v = data.get(k)
            if v is not None and (isinstance(v, bool) or not isinstance(v, int) or v < 0):
                raise InputError(
                    path,
                    f"{field}.{k}" if field else k,
                    f"expected a non-negative integer, got {v!r:.40}",
                )

    count(search, "", ("candidates", "feasible", "infeasible"))
    if "infeasible_reasons" in search:  # (absent from runs made before it was written)
        reasons = _object(path, search, key="infeasible_reasons")
        if len(reasons) > MAX_INFEASIBLE_KINDS + 1:
            raise InputError(
                path,
                "infeasible_reasons",
                f"at most {MAX_INFEASIBLE_KINDS + 1} kinds, got {len(reasons):,}",
            )
        for kind, n in reasons.items():
            if not (0 < len(kind) <= MAX_KIND_CHARS and kind.isprintable()):
                raise InputError(
                    path,
                    "infeasible_reasons",
                    f"a kind is 1-{MAX_KIND_CHARS} printable characters, got {kind!r:.40}",
                )
            if isinstance(n, bool) or not isinstance(n, int) or n < 0:
                raise InputError(
                    path,
                    f"infeasible_reasons.{kind}",
                    f"expected a non-negative integer, got {n!r:.40}",
                )
    _numbers(path, search, "", ("best_collision_probability", "best_log10_risk"))
    p = search.get("best_collision_probability")
    if p is not None and not 0.0 <= p <= 1.0:
        raise InputError(path, "best_collision_probability", f"expected 0..1, got {p!r:.40}")
    settings = _object(path, search, key="settings")
    count(settings, "settings", ("budget", "seed", "seeds", "top"))
    if "speed_limits" in search:  # printed per environment (a NaN speed printed "nan")
        for env, lim in _object(path, search, key="speed_limits").items():
            field = f"speed_limits.{str(env)[:40]}"
            lim = _object(path, lim, field)
            for key, hi in (("speed_kmh", 360.0), ("visibility_m", math.inf)):
                v = lim.get(key)
                if v is not None and (
                    isinstance(v, bool) or not isinstance(v, int | float) or not 0.0 <= v < hi
                ):
                    raise InputError(
                        path, f"{field}.{key}", f"expected a finite number >= 0, got {v!r:.40}"
                    )
            if not isinstance(lim.get("rule", ""), str):
                raise InputError(path, f"{field}.rule", "expected a string")
    lve = _object(path, search, key="lookup_vs_exact")
    count(
        lve,
        "lookup_vs_exact",
        (
            "reevaluated",
            "sensor_critical_both",
            "sensor_critical_exact",
            "sensor_critical_lookup",
            "top10_overlap",
        ),
    )
    _numbers(
        path,
        lve,
        "lookup_vs_exact",
        ("max_abs_diff_collision_probability", "mean_abs_diff_collision_probability"),
    )
    for fam, d in _object(path, search, key="per_family").items():
        count(
            _object(path, d, f"per_family.{fam[:40]}"),
            f"per_family.{fam[:40]}",
            ("budget", "feasible", "sensor_critical_by_lookup", "threats", "unavoidable_by_lookup"),
        )


def read_nearfield(path: Path) -> dict[str, Any]:
    """``nearfield.json`` of a run, its fields as the report reads them checked."""
    d = _object(path, read_json(path))
    bs = _object(path, d, key="blind_spot_m2")
    _numbers(path, bs, "blind_spot_m2", ("difference",))
    holes = bs.get("holes", [])
    # each hole's numbers, as the summary places and names them (checked there after the
    # scenario figures were drawn: hostile round 24)
    if not isinstance(holes, list) or not all(
        isinstance(h, dict)
        and isinstance(h.get("bounds_m"), list)
        and len(h["bounds_m"]) == 4
        and isinstance(h.get("centroid_m"), list)
        and len(h["centroid_m"]) == 2
        and all(
            isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
            for v in (h.get("area_m2"), *h["bounds_m"], *h["centroid_m"])
        )
        for h in holes
    ):
        raise InputError(
            path,
            "blind_spot_m2",
            "unreadable: a hole's area_m2, bounds_m and centroid_m are finite numbers",
        )
    _numbers(path, bs, "blind_spot_m2", ("exact", "grid"), ("exact",), at_least=0.0)
    unc = _object(path, d, key="uncovered_0p1m_m2")
    _numbers(path, unc, "uncovered_0p1m_m2", ("difference",))
    _numbers(path, unc, "uncovered_0p1m_m2", ("exact", "grid"), at_least=0.0)
    _numbers(path, _object(path, d, key="window"), "window", ("radius_m",), at_least=0.0)
    if "unseen_any_height_m2" in d:  # (absent from runs made before it was written)
        _numbers(
            path,
            _object(path, d, key="unseen_any_height_m2"),
            "unseen_any_height_m2",
            ("exact", "enclosed", "open_to_outside"),
            ("exact",),
            at_least=0.0,
        )
    if not isinstance(d.get("method", ""), str | dict):
        raise InputError(path, "method", "expected a string or an object")
    return d


#: What a report or comparison shows of one run: at most this many figures and bytes of
#: them in all (hostile round 26: 64 figures of 19 MB each took a report to 5.4 GB and a
#: 0.94 GB report.html). The default job shows 15 figures of 2.1 MB in all; a job over
#: 100 environments about 200 of 14 MB.
MAX_RUN_FIGURES = 500
MAX_RUN_FIGURE_BYTES = 100_000_000


def checked_nearfield(path: Path, vehicle: str | None) -> dict[str, Any]:
    """``nearfield.json`` read and checked (``read_nearfield``) and ``vehicle``'s (None:
    not recorded, not checked): what a report or comparison prints, read where it is
    used (hostile round 26: a file replaced after the check was printed unchecked)."""
    d = read_nearfield(path)
    got = d.get("system")
    if vehicle is not None and got != vehicle:  # another vehicle's near field as this one's
        raise InputError(
            path,
            "system",
            f"{str(got)[:64]!r} is not this run's vehicle ({vehicle!r}); compute it "
            f"with `sensorgap nearfield --vehicle <the run's vehicle> --out "
            f"{path.parent.parent.name}/nearfield`",
        )
    return d


def checked_map_summary(path: Path, vehicle: str | None, named: bool = True) -> dict[str, Any]:
    """A coverage map's ``summary.json`` read and checked: ``vehicle``'s (None: not
    checked) and (``named``: a run's own map, not one a comparison computed into a folder
    named by ``compare_maps.slug``) named after its target and environment
    (``_check_map_identity``), the areas and the cell size it prints finite numbers >= 0
    (text or NaN was printed)."""
    cs = _object(path, read_json(path))
    if vehicle is not None:
        _check_map_identity(path, cs, vehicle, named)
    _numbers(
        path,
        _object(path, cs, key="area_m2_by_level"),
        "area_m2_by_level",
        ("pd=1.0", "pd>=0.8", "pd>=0.5", "pd>0", "pd=0"),
        at_least=0.0,
    )
    _numbers(path, _object(path, cs, key="grid"), "grid", ("resolution_m",), at_least=0.0)
    return cs


def check_pieces(folder: Path, vehicle: str | None) -> None:
    """The near field, coverage maps and figures of a run (or job) folder that a report or
    a comparison shows, checked before any work: ``nearfield.json`` (``read_nearfield``)
    and each map's ``summary.json`` are ``vehicle``'s (None: not recorded, not checked),
    their printed numbers finite, no map without its summary, and every figure shown
    (``nearfield.png``, ``coverage/*/coverage.png``, ``farfield/*/farfield.png``) a PNG
    within ``document.MAX_FIGURE_BYTES`` and ``MAX_FIGURE_PIXELS``, the far field's CSV
    files within ``MAX_CSV_BYTES`` (hostile round 25:
    ``compare`` showed another vehicle's near field and maps, printed "nan", and a PNG
    claiming 10,000 x 10,000 pixels took 1.6 GB), each map's ``coverage.npz`` readable
    (``coverage.outputs.read_coverage_npz``: a damaged map was found after the scenario
    figures were drawn), at most ``MAX_RUN_FIGURES`` figures and ``MAX_RUN_FIGURE_BYTES``
    of them in all; else ``InputError``."""
    nf = folder / "nearfield" / "nearfield.json"
    if os.path.lexists(nf):  # a pipe or folder there is refused, not taken for none
        checked_nearfield(nf, vehicle)
    for npz in sorted((folder / "coverage").glob("*/coverage.npz")):
        read_coverage_npz(npz)  # its cells and axes (the summary reads it after the figures)
        if not os.path.lexists(npz.parent / "summary.json"):  # whose map it is, unknown
            raise InputError(
                npz,
                "",
                "a coverage map without its summary.json: whose vehicle and inputs it "
                "shows cannot be checked (hostile round 24: another vehicle's map was "
                "reported as this one's); compute it with `sensorgap coverage`",
            )
    for s in sorted((folder / "coverage").glob("*/summary.json")):
        checked_map_summary(s, vehicle)
    figures = [
        *sorted((folder / "nearfield").glob("nearfield.png")),
        *sorted((folder / "coverage").glob("*/coverage.png")),
        *sorted((folder / "farfield").glob("*/farfield.png")),
    ]
    if len(figures) > MAX_RUN_FIGURES:
        raise InputError(
            folder, "", f"holds {len(figures)} figures to show; at most {MAX_RUN_FIGURES}"
        )
    total = 0
    for png in figures:
        total += regular_file_size(png)
        if total > MAX_RUN_FIGURE_BYTES:
            raise InputError(
                folder,
                "",
                f"its figures to show exceed {MAX_RUN_FIGURE_BYTES} bytes in all (at "
                f"{png.relative_to(folder).as_posix()[:80]}); a report embeds every one",
            )
        embedded_png(png)
    for table in (
        *sorted((folder / "farfield").glob("table_iv.csv")),
        *sorted((folder / "farfield").glob("*/farfield.csv")),
    ):
        _check_csv_size(table)


def read_catalog(path: Path) -> dict[str, Any]:
    """``catalog.json`` of a run, checked (``export.simulate.read_catalog_index``, and a
    road for every scenario)."""
    index, entries = read_catalog_index(path)
    for i, e in enumerate(entries):
        if not isinstance(e.get("road"), str):
            raise InputError(
                path,
                f"scenarios[{i}].road",
                "malformed catalog index: expected a relative path inside the catalog",
            )
    return index


#: A CSV file of a run or job folder that a report or comparison reads (``table_iv.csv``,
#: a far field's ``farfield.csv``: 0.63 MB for the job's 200 m): at most this many bytes.
#: A 283 MB table_iv.csv of valid rows took report to 5.4 GB (hostile round 25).
MAX_CSV_BYTES = 20_000_000


def _check_csv_size(path: Path) -> None:
    try:
        regular_file_size(path, MAX_CSV_BYTES)
    except OSError as exc:
        raise InputError(path, "", f"unreadable CSV: {exc}") from None


def read_csv(path: Path) -> list[dict[str, str]]:
    """A CSV file of the run folder as rows (at most ``MAX_CSV_BYTES``)."""
    _check_csv_size(path)
    try:
        with path.open(encoding="utf-8", newline="") as f:
            return list(csv.DictReader(f))
    except (OSError, csv.Error, UnicodeDecodeError) as exc:
        raise InputError(path, "", f"unreadable CSV: {exc}") from None


#: The columns of ``farfield/table_iv.csv`` (``analysis.paper``, written by the job).
TABLE_IV_COLUMNS = ("environment", "level", "metres")


def read_table_iv(path: Path) -> list[dict[str, str]]:
    """``farfield/table_iv.csv`` checked: its three columns in every row, each environment
    a name (a folder of ``farfield/`` whose figure the report embeds: no path), each
    length a finite number >= 0 (m); else ``InputError`` naming the file and the row
    (hostile round 24: a missing column or a short row was an internal error, an
    absolute path as environment embedded a figure from outside the run)."""
    from sensorgap.config.common import name_problem

    rows = read_csv(path)
    for i, row in enumerate(rows):
        where = f"row {i + 2}"
        missing = [c for c in TABLE_IV_COLUMNS if not isinstance(row.get(c), str)]
        if missing:
            raise InputError(
                path, where, f"no {missing[0]} (columns: {', '.join(TABLE_IV_COLUMNS)})"
            )
        why = name_problem(row["environment"])
        if why is None and ("/" in row["environment"] or row["environment"].startswith(".")):
            why = "a name, not a path"
        if why is not None:
            raise InputError(path, f"{where}.environment", why)
        try:
            metres = float(row["metres"])
        except ValueError:
            metres = math.nan
        if not (math.isfinite(metres) and metres >= 0.0):
            raise InputError(
                path,
                f"{where}.metres",
                f"expected a length >= 0 (m), got {cut_quoted(repr(row['metres']))}",
            )
    return rows


def fmt(v: Any, digits: int = 4) -> str:
    """A value as table text."""
    if v is None:
        return ""
    if isinstance(v, float):
        if math.isnan(v) or math.isinf(v):
            return str(v)
        return f"{v:.{digits}g}"
    return str(v)


#: Where the reference notes cited as "physics.md" in parameter sources live.
PHYSICS_NOTE = (
    'Sources that cite "physics.md" refer to the project\'s reference notes on parameter '
    "values and on numerical pitfalls of the paper's equations. They are not part of the "
    "repository or of this report: they are kept beside the repository, in the development "
    'workspace at shared/reference/physics.md. The pitfalls ("physics.md pitfall N") are '
    "explained in docs/models.md; for a value, check the primary source named in the same "
    "entry (a data sheet, a standard or a paper)."
)


def _vehicle_section(system: System) -> Section:
    kinds: dict[str, int] = {}
    for s in system.sensors:
        kinds[s.type_name] = kinds.get(s.type_name, 0) + 1
    body = system.config.vehicle
    return Section(
        "vehicle",
        f"Vehicle: {system.name}",
        [
            Para(
                f"Source: {system.source.name}. Body {body.length_m} m x {body.width_m} m x "
                f"{body.height_m} m, wheelbase {body.wheelbase_m} m; vehicle frame ISO 8855 "
                "(x forward, y left, z up), origin on the ground under the rear axle. "
                f"{len(system.sensors)} sensors ("
                + ", ".join(f"{n} {k}" for k, n in kinds.items())
                + "); their mounts, fields of view, ranges and every physical parameter with "
                "its source are in the appendix."
            ),
        ],
    )


def _sensor_setup_section(system: System) -> Section:
    mounts = []
    for s in system.sensors:
        m = s.mount
        mounts.append(
            [
                s.id,
                s.type_name,
                f"{m.x:.2f}, {m.y:.2f}, {m.z:.2f}",
                f"{math.degrees(m.yaw):.1f}",
                f"{math.degrees(m.pitch):.1f}",
                f"{math.degrees(m.hfov):.1f}",
                f"{math.degrees(m.vfov):.1f}",
                f"{m.min_range:g}",
                f"{m.max_range:g}",
                s.roc.kind,
            ]
        )
    params = []
    for name, dev in system.config.devices.items():
        for key, val in sorted(dev.params().items()):
            if isinstance(val, dict | list) or val is None:
                continue
            params.append([name, dev.type, key, fmt(val, 6), dev.sources.get(key, "")])
    blocks: list[Block] = [
        Table(
            [
                "sensor",
                "type",
                "position x, y, z [m]",
                "yaw [deg]",
                "pitch [deg]",
                "HFOV [deg]",
                "VFOV [deg]",
                "min range [m]",
                "max range [m]",
                "ROC",
            ],
            mounts,
            "Sensor setup (as the paper's Table III)",
        ),
        Table(
            ["device", "type", "parameter", "value", "source"],
            params,
            "Every physical parameter with its source",
        ),
    ]
    if any("physics.md" in str(r[4]) for r in params):
        blocks.append(Para(PHYSICS_NOTE))
    return Section("sensor-setup", f"Sensor setup of {system.name}", blocks)


def _environments_section(settings: dict[str, Any], run: RunFolder) -> Section:
    envs = run.environments()
    used = settings.get("environments") or list(envs)
    rows = []
    for name in used:
        e = envs.get(name)
        if e is None:
            continue
        sun = (
            "none"
            if e.sun is None
            else f"az {e.sun.azimuth_deg:g} el {e.sun.elevation_deg:g} deg ({e.sun.frame}, "
            f"{'visible' if e.sun.visible else 'not visible'})"
        )
        rows.append(
            [
                name,
                fmt(e.rain_mm_h),
                fmt(e.snow_mm_h),
                fmt(e.visibility_m),
                fmt(e.temperature_c),
                fmt(e.irradiance_w_m2),
                fmt(e.roc_shift_db),
                sun,
            ]
        )
    targets = [
        [
            t.name,
            fmt(t.rcs_m2),
            fmt(t.camera_cross_section_m2),
            f"{t.length_m} x {t.width_m} x {t.height_m}",
            fmt(t.reference_height_m),
            "; ".join(f"{k}: {v}" for k, v in sorted(t.sources.items())),
        ]
        for t in run.targets().values()
    ]
    return Section(
        "environments",
        "Environments and targets",
        [
            Table(
                [
                    "preset",
                    "rain [mm/h]",
                    "snow [mm/h]",
                    "visibility [m]",
                    "temperature [C]",
                    "irradiance [W/m2]",
                    "ROC shift [dB]",
                    "sun",
                ],
                rows,
                "Environments (" + _source(run, "environments") + ")",
            ),
            Table(
                [
                    "target",
                    "RCS [m2]",
                    "camera cross-section [m2]",
                    "l x w x h [m]",
                    "reference height [m]",
                    "sources",
                ],
                targets,
                "Target classes (" + _source(run, "targets") + ")",
            ),
        ],
    )


def _source(run: RunFolder, key: str) -> str:
    """Where an input of the report comes from: the run's recorded copy (with the original
    file's name) or the shipped presets."""
    p = run.input_path(key)
    if p is None:
        return f"shipped presets, {templates_dir().name}/{key}.toml"
    orig = Path(str((run.info.get("inputs") or {}).get(key, {}).get("path", p.name)))
    return f"recorded in the run: {p.relative_to(run.folder).as_posix()}, from {orig.name}"


def _nearfield_section(folder: Path) -> Section:
    nf = folder / "nearfield" / "nearfield.json"
    if not nf.is_file():
        return Section("nearfield", "Near-field blind spots", [Para(NOT_RUN)])
    d = read_nearfield(nf)
    bs, u = d.get("blind_spot_m2", {}), d.get("uncovered_0p1m_m2", {})
    unseen = d.get("unseen_any_height_m2")
    rows = [
        [
            "blind spot: enclosed, no sensor at any height (paper Fig. 5)",
            fmt(bs.get("exact")),
            fmt(bs.get("grid")),
            fmt(bs.get("difference")),
        ]
    ]
    if isinstance(unseen, dict):
        rows.append(
            [
                "no sensor at any height, in all (enclosed and open to the outside)",
                fmt(unseen.get("exact")),
                "(exact only)",
                "",
            ]
        )
    rows.append(
        [
            "uncovered at 0.1 m height",
            fmt(u.get("exact")),
            fmt(u.get("grid")),
            fmt(u.get("difference")),
        ]
    )
    blocks: list[Any] = [
        Table(
            ["quantity", "exact polygons [m2]", "grid [m2]", "difference [m2]"],
            rows,
            f"Near field within {d.get('window', {}).get('radius_m', 5)} m of the body",
        )
    ]
    method = d.get("method")
    if isinstance(method, dict):
        blocks.append(
            Para(
                "Method: "
                + "; ".join(f"{k.replace('_', ' ')}: {v}" for k, v in method.items())
                + "."
            )
        )
    elif method:
        blocks.append(Para(f"Method: {method}."))
    png = folder / "nearfield" / "nearfield.png"
    if png.is_file():
        blocks.append(
            Image(png, "Near-field coverage: blind spots (Fig. 5 style)", "nearfield/nearfield.png")
        )
    return Section("nearfield", "Near-field blind spots", blocks)


def _coverage_section(folder: Path) -> Section:
    cov = folder / "coverage"
    dirs = (
        sorted(p for p in cov.glob("*") if (p / "summary.json").is_file()) if cov.is_dir() else []
    )
    if not dirs:
        return Section("coverage", "Far-field coverage maps per environment", [Para(NOT_RUN)])
    rows, subs = [], []
    for d in dirs:
        s = _object(d / "summary.json", read_json(d / "summary.json"))
        a = _object(d / "summary.json", s, key="area_m2_by_level")
        rows.append(
            [
                d.name,
                *(fmt(a.get(k)) for k in ("pd=1.0", "pd>=0.8", "pd>=0.5", "pd>0", "pd=0")),
                fmt(_object(d / "summary.json", s, key="grid").get("resolution_m")),
            ]
        )
        if (d / "coverage.png").is_file():
            subs.append(
                Section(
                    f"coverage-{d.name}",
                    d.name,
                    [
                        Image(
                            d / "coverage.png",
                            f"Fused Pd, {d.name}: target "
                            f"{s.get('target_model', 'point')} (same colour scale in every "
                            "map; vehicle outline and sensor fields of view drawn)",
                            f"coverage/{d.name}/coverage.png",
                        )
                    ],
                )
            )
    return Section(
        "coverage",
        "Far-field coverage maps per environment",
        [
            Table(
                [
                    "map",
                    "Pd = 1 [m2]",
                    "Pd >= 0.8 [m2]",
                    "Pd >= 0.5 [m2]",
                    "Pd > 0 [m2]",
                    "Pd = 0 [m2]",
                    "cell [m]",
                ],
                rows,
                "Area per Pd level",
            )
        ],
        subs,
    )


def _farfield_section(folder: Path) -> Section:
    tab = folder / "farfield" / "table_iv.csv"
    if not tab.is_file():
        return Section("table-iv", "Table IV: Pd along the lane ahead", [Para(NOT_RUN)])
    rows = read_table_iv(tab)
    envs = list(dict.fromkeys(r["environment"] for r in rows))
    levels = list(dict.fromkeys(r["level"] for r in rows))
    val = {(r["environment"], r["level"]): r["metres"] for r in rows}
    blocks: list[Any] = [
        Para(
            "Length (m) of the car path in the right lane of roads/motorway_r500.xodr ahead "
            "of the ego (left lane, 50 m before the clothoid into the R = 500 m curve) at "
            "each detection level, as in the paper's Table IV."
        ),
        Table(
            ["level", *envs],
            [[lv, *(val.get((e, lv), "") for e in envs)] for lv in levels],
            "Table IV style (metres)",
        ),
    ]
    subs = []
    for e in envs:
        png = folder / "farfield" / e / "farfield.png"
        if png.is_file():
            subs.append(
                Section(
                    f"farfield-{e}",
                    e,
                    [Image(png, f"Pd along the target lane, {e}", f"farfield/{e}/farfield.png")],
                )
            )
    return Section("table-iv", "Table IV: Pd along the lane ahead", blocks, subs)


def _per_family_table(search: dict[str, Any] | None, rows: list[dict[str, Any]]) -> list[Block]:
    per = (search or {}).get("per_family")
    if not isinstance(per, dict) or not per:
        return []
    ranked: dict[str, int] = {}
    for r in rows:
        ranked[str(r.get("family"))] = ranked.get(str(r.get("family")), 0) + 1
    return [
        Table(
            [
                "family",
                "candidates",
                "feasible",
                "threats",
                "sensor-critical (lookup)",
                "unavoidable (lookup)",
                "ranked",
            ],
            [
                [
                    f,
                    *(
                        fmt(d.get(k))
                        for k in (
                            "budget",
                            "feasible",
                            "threats",
                            "sensor_critical_by_lookup",
                            "unavoidable_by_lookup",
                        )
                    ),
                    str(ranked.get(f, 0)),
                ]
                for f, d in per.items()
            ],
            "Search per family (summary.json; counts of the lookup evaluation)",
        )
    ]


def _speed_limit_table(search: dict[str, Any] | None) -> list[Block]:
    lims = (search or {}).get("speed_limits")
    if not isinstance(lims, dict) or not lims:
        return []
    rows = [
        [
            str(e),
            "not bounded"
            if not isinstance(d, dict) or d.get("speed_kmh") is None
            else fmt(d.get("speed_kmh")),
            fmt(d.get("visibility_m")) if isinstance(d, dict) else "",
            str(d.get("rule", "")) if isinstance(d, dict) else "",
        ]
        for e, d in lims.items()
    ]
    return [
        Table(
            ["environment", "highest ego speed [km/h]", "visibility [m]", "rule"],
            rows,
            "Lawful ego speed per environment (StVO 3(1), driving within sight; "
            "docs/search.md 'Speed within sight'): the search never drove faster",
        )
    ]


def _param_rows(spec: ScenarioSpec) -> list[list[str]]:
    rows = []
    for k, v in spec.params.items():
        text = fmt(v, 6)
        if k.endswith("_m_s") and isinstance(v, float):
            text += f" ({v * KMH:.1f} km/h)"
        rows.append([k, text])
    if spec.sun_deg is not None:
        rows.append(
            [
                "sun azimuth (compass, world frame) / elevation [deg]",
                f"{spec.sun_deg[0]:g} / {spec.sun_deg[1]:g}",
            ]
        )
    return rows


def _scenarios_section(
    run: RunFolder, out_img: Path, search: dict[str, Any] | None
) -> tuple[Section, list[list[str]], list[RankedScenario] | None]:
    folder = run.folder
    if not (folder / "ranking.json").is_file():
        return Section("scenarios", "Critical scenarios", [Para(NOT_RUN)]), [], None
    catalog = folder / "catalog.json"
    exported = read_catalog(catalog) if catalog.is_file() else None
    files = {s["scenario_id"]: s for s in exported["scenarios"]} if exported else {}
    system = run.system()
    ev = run.evaluator("lookup")
    try:
        rule = DetectionRule.parse(str(run.settings.get("detection", "cumulative")))
    except InputError:
        raise InputError(
            folder / "ranking.json",
            "settings.detection",
            f"expected 'cumulative' or M/N (e.g. 3/5), got {run.settings.get('detection')!r}",
        ) from None
    exact = run.evaluator("exact", rule)
    metrics = metric_names()
    overview, subs, errors = [], [], []
    ranked: list[RankedScenario] = []
    types = {s.id: s.type_name for s in system.sensors}
    for row in run.rows:
        spec = ScenarioSpec.from_row(row, system, folder / "ranking.json", run)
        tr = scenario_trace(spec, exact)
        png = out_img / f"scenario_{spec.rank:03d}.png"
        scenario_figure(spec, ev, tr, png)
        f = files.get(spec.scenario_id)
        # the reason's per-sensor causes, recomputed exactly as the search did (its text
        # is the row's reason; tested)
        why = explain_spec(spec, exact)
        # the sensors that confirm at the named step: the reaction model's moving-only ones
        # too where the target moves there (``Evaluator.confirming``, as the explanation)
        speed = float(spec.scenario.target.speed[named_step(tr)])
        item = RankedScenario(
            row,
            spec,
            tr,
            why,
            tuple(system.sensors[i].id for i in exact.confirming(speed)),
            {"file": str(f["file"]), "road": str(f["road"])}
            if f and exported is not None
            else None,
        )
        ranked.append(item)
        p_look = row.get("lookup_collision_probability")
        p_exact = row.get("collision_probability")
        errors.append(
            [
                str(spec.rank),
                spec.scenario_id,
                fmt(p_look),
                fmt(p_exact),
                ""
                if p_look is None or p_exact is None
                else fmt(abs(float(p_look) - float(p_exact))),
            ]
        )
        overview.append(
            [
                str(spec.rank),
                spec.scenario_id,
                str(row.get("class", "")),
                spec.family.name,
                str(row.get("environments") or row.get("environment")),
                spec.target.name,
                fmt(p_exact),
                fmt(row.get("impact_speed_kmh")),
                fmt(row.get("t_safe_s")),
                fmt(row.get("detection_margin_s")),
                str(row.get("dominant_effect", "")),
            ]
        )
        params = _param_rows(spec)
        mets = [[m, fmt(row.get(m), 6)] for m in metrics if m in row]
        blocks: list[Any] = [
            Para(f"In words: {weakness_sentence(item, types)}"),
            Para(f"Why critical (as the search recorded it): {row.get('reason', '')}"),
            Table(["parameter", "value"], params, "Parameters"),
            Table(["metric", "value"], mets, "Metrics (exact evaluation)"),
            Image(
                png,
                f"Rank {spec.rank}: target path over the Pd map (ego frame), Pd(t) "
                "and probability still undetected",
                f"{REPORT_DIR}/{png.name}",
            ),
        ]
        if f and exported is not None:
            blocks.append(
                Links(
                    [
                        (f"{f['file']} (OpenSCENARIO {exported['osc_version']})", f["file"]),
                        (f"{f['road']} (OpenDRIVE)", f["road"]),
                    ]
                )
            )
        else:
            blocks.append(Para("Not exported (run `sensorgap export --run DIR`)."))
        subs.append(
            Section(
                f"scenario-{spec.rank}",
                f"{spec.rank}. {spec.family.name} in {row.get('environment')} ({spec.scenario_id})",
                blocks,
            )
        )
    head: list[Block] = [
        Para(
            f"{len(run.rows)} ranked scenarios of the search (strategy "
            f"{run.settings.get('strategy')}, proposals by Pd {run.settings.get('pd')}, every "
            "number here re-evaluated exactly with target bodies). Sensor-critical: a vehicle "
            "with perfect perception and the same reaction model avoids the collision, this "
            "one confirms the target too late with the given probability (reaction model: "
            f"{run.settings.get('reaction', 'the vehicle file')}). Ranked by collision "
            "probability, then impact speed; scenarios that collide even with perfect "
            "perception are listed apart (unavoidable.csv). Scenarios start with a path TTC "
            f">= {START_TTC_S:g} s. Perfect perception is limited to the line of sight: a "
            "target hidden behind another road user until too late for any sensor or driver "
            "is unavoidable, not sensor-critical; one that perfect perception avoids by less "
            "than one confirmation window (0.25 s) is marginal, listed with the unavoidable "
            "ones (docs/models.md, collision outcome)."
        ),
        Table(
            [
                "rank",
                "scenario",
                "class",
                "family",
                "environments",
                "target",
                "P(collision)",
                "impact [km/h]",
                "t_safe [s]",
                "margin [s]",
                "dominant effect",
            ],
            overview,
            "Ranking",
        ),
        *_per_family_table(search, run.rows),
        *_speed_limit_table(search),
    ]
    return Section("scenarios", "Critical scenarios", head, subs), errors, ranked


def _accuracy_section(folder: Path, errors: list[list[str]]) -> Section:
    blocks: list[Any] = [
        Table(
            ["setting", "value", "measured error"],
            [
                [
                    "search Pd evaluation (proposals only)",
                    "lookup maps of target bodies (outline "
                    "erosion per 15 deg heading bin), bilinear",
                    "see the table below (this run)",
                ],
                ["reported numbers", "exact evaluation of target bodies", "0 (the reference)"],
                ["lookup map cell", f"{MAP_RESOLUTION_M} m", "exact at cell centres (points)"],
                ["grid saturation cull", "fused miss probability <= 1e-10", "|delta Pd| <= 1e-10"],
                ["lane table step", "0.1 m", "<= 2.5e-6 m (R = 500 m arc)"],
                ["near-field grid", "0.05 m", "blind-spot area vs exact polygons: see above"],
            ],
            "Speed/accuracy settings used",
        )
    ]
    if errors:
        blocks.append(
            Table(
                [
                    "rank",
                    "scenario",
                    "P(collision) proposed (lookup)",
                    "P(collision) reported (exact)",
                    "abs difference",
                ],
                errors,
                "Lookup vs exact for the ranked scenarios of this run",
            )
        )
    trade = folder / "tradeoff" / "tradeoff.md"
    if trade.is_file():
        blocks.append(Para("Trade-off measurements: tradeoff/tradeoff.md."))
    return Section("accuracy", "Speed/accuracy settings and their measured error", blocks)


ASSUMPTIONS = [
    "Phenomenological sensor models of Ponn et al. (IEEE IV 2019), eq. 1-11; every "
    "parameter and equation with its source in docs/models.md.",
    "Detections at consecutive 20 Hz cycles are independent (P_undet = product of (1 - Pd)); "
    "real trackers correlate cycles, so P_undet is optimistic for persistent occlusion and "
    "pessimistic for flicker.",
    "Fusion of sensors by eq. 11 (independent sensors); a target counts as confirmed for "
    "braking after M of N cycles detected by the sensor types of the vehicle's reaction "
    "model (templates/reactions.toml).",
    "Occlusion: other road users of a scene (the families' lead cars, parked cars) are "
    "opaque boxes; the ego's own body (its box) hides what lies behind it from sensors "
    "mounted outside it; nothing else occludes (no buildings, terrain or vegetation).",
    "A target is its box (targets.toml) at its heading: per sensor the visible part of its "
    "facing outline decides (a camera needs half of it, a lidar a tenth, radar and "
    "ultrasonic any reflecting part), with the SNR of the visible part (docs/models.md).",
    "Collision outcome: the vehicle brakes along its own path (latency, jerk-limited "
    "deceleration bounded by road friction) once the target is confirmed and a threat; "
    "the target keeps its planned path.",
    "Glare: direct sun within a camera's field of view (+10 deg margin, cos^2 fade) adds "
    "a veil on the target's image (Stiles-Holladay, falling with the target's angle from "
    "the sun) that costs contrast, averaged over the target's pixels: it hides a large "
    "target within a few degrees of the sun, a small or distant one over a wider angle "
    "(veiling glare constants are estimates, docs/models.md).",
    "Lidar has no solar background term (keeps A unchanged under glare, as in the paper).",
    "Open loop but for braking: the ego keeps its lane and speed unless it brakes for the "
    "target; no evasive steering.",
    "Weather attenuation from ITU-R and published fits; ROC curves calibrated (estimates) to "
    "reproduce the paper's Table IV within 20 m (docs/models.md).",
]


def _paras(texts: list[str]) -> list[Block]:
    return [Para(t) for t in texts]


def build(folder: Path) -> tuple[str, list[str], Section, list[Section]]:
    """Title, meta lines, the summary page and the sections of the report of
    ``folder``."""
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(folder, "", not_a_run_folder(folder))
    for name in (REPORT_DIR, "report.html", "report.md"):  # written through, or refused
        if (folder / name).is_symlink():  # by atomic_path after the figures were redrawn
            raise InputError(
                folder / name,
                "",
                "is a symbolic link; report writes only inside the run folder (remove the link)",
            )
    if (folder / STORE_FILE).is_file() and not (folder / "ranking.json").is_file():
        # a search killed before its ranking: a report would say "no search in this run"
        # and stay behind, certified, after the resumed search (hostile round sixteen)
        raise InputError(
            folder / "ranking.json",
            "",
            f"missing: the search in this folder did not finish ({STORE_FILE} holds its "
            "candidates); finish it with `sensorgap search ... --resume` (same options) "
            "and report then",
        )
    run = open_run(folder, ranking=False)
    info = run.info
    settings = {**run.settings, **info.get("settings", {})}
    vehicle = run.vehicle_ref
    if not vehicle:
        raise InputError(
            folder, "", "neither run.json nor ranking.json says which vehicle this run is for"
        )
    system = run.system()
    check_pieces(folder, system.name)  # near field, coverage maps, figures: before any work
    if (folder / "catalog.json").is_file():
        read_catalog(folder / "catalog.json")
    if (folder / "anchors" / "anchors.json").is_file():
        a = folder / "anchors" / "anchors.json"
        rows = _object(a, read_json(a)).get("anchors")
        if not isinstance(rows, list) or not all(isinstance(r, dict) for r in rows):
            raise InputError(a, "anchors", "expected a list of objects")
    search = (
        read_json(folder / "summary.json")
        if (folder / "summary.json").is_file() and (folder / "ranking.json").is_file()
        else None
    )
    if search is not None and not isinstance(search, dict):
        raise InputError(folder / "summary.json", "", "expected a JSON object")
    for fam, d in (
        _object(folder / "summary.json", search, key="per_family") if search is not None else {}
    ).items():
        _object(folder / "summary.json", d, f"per_family.{fam[:40]}")
    if search is not None:
        _check_search_summary(folder / "summary.json", search)
        _check_stability(
            folder / "summary.json", _object(folder / "summary.json", search, key="stability")
        )
    img = folder / REPORT_DIR  # created once every input above is checked
    img.mkdir(parents=True, exist_ok=True)
    scen, errors, ranked = _scenarios_section(run, img, search)
    lve, n_unavoidable = None, 0
    if ranked is not None:
        data = run.data
        lve = data.get("lookup_vs_exact") if isinstance(data, dict) else None
        n_unavoidable = len(data.get("unavoidable") or []) if isinstance(data, dict) else 0
    robust = (
        finding_robustness(run, system, [r.row for r in ranked[:ROBUSTNESS_TOP]])
        if ranked
        else None
    )
    front = summary_section(
        folder,
        system,
        settings,
        ranked,
        search,
        lve if isinstance(lve, dict) else None,
        n_unavoidable,
        robust,
    )
    now = versions()
    ver = info.get("versions") or now
    changed = sorted(k for k in set(ver) | set(now) if str(ver.get(k)) != str(now.get(k)))
    repro = info.get("command") or ["sensorgap", "report", "--run", str(folder)]
    sections = [
        _vehicle_section(system),
        _nearfield_section(folder),
        _coverage_section(folder),
        _farfield_section(folder),
        scen,
        robustness_section(robust),
        anchors_section(folder),
        Section("assumptions", "Model assumptions and limitations", _paras(ASSUMPTIONS)),
        _accuracy_section(folder, errors),
        Section(
            "reproduce",
            "Software, configuration and reproduction",
            [
                Table(
                    ["package", "version (run)", "version (this report)"],
                    [
                        [k, str(ver.get(k, "-")), str(now.get(k, "-"))]
                        for k in sorted(set(ver) | set(now))
                    ],
                    "Software versions",
                ),
                *(
                    [
                        Para(
                            "The run was made with other software than this report ("
                            + ", ".join(changed)
                            + "): its stored results (ranking, search store, exported "
                            "scenarios) are the run's; the figures and tables were rebuilt "
                            "from them with this report's versions."
                        )
                    ]
                    if changed
                    else []
                ),
                Table(
                    ["file", "SHA-256"],
                    [[k, v] for k, v in sorted(info.get("config_sha256", {}).items())],
                    "Configuration files",
                ),
                Table(
                    ["setting", "value"],
                    [[k, json.dumps(v, sort_keys=True)] for k, v in sorted(settings.items())],
                    "Settings",
                ),
                Para("Reproduce with: " + shell_join(str(a) for a in repro)),
                Para("Every file of the folder with its SHA-256: manifest.json."),
            ],
        ),
        Section(
            "appendix",
            "Appendix: sensor setup, parameter sources, environments and targets",
            [],
            [_sensor_setup_section(system), _environments_section(settings, run)],
        ),
    ]
    meta = [
        f"Run folder: {folder.name}. Vehicle: {system.name} ({vehicle}). "
        f"Generated (UTC): {utc_now()}"
    ]
    return f"sensorgap audit report: {system.name}", meta, front, sections


def _check_map_identity(
    path: Path, summary: dict[str, Any], vehicle: str, named: bool = True
) -> None:
    """A run's coverage map (``path``: its ``summary.json``) is this run's vehicle's and
    (``named``) is named ``<target>_<environment>`` after what it was computed for
    (hostile round sixteen: another vehicle's map, or a car/clear map named
    ``truck_fog_50``, was reported as this one's), else ``InputError``."""
    got = summary.get("vehicle")
    if got != vehicle:
        raise InputError(
            path,
            "vehicle",
            f"{str(got)[:64]!r} is not this run's vehicle ({vehicle!r}); compute the map with "
            "`sensorgap coverage --vehicle <the run's vehicle>`",
        )
    want = f"{summary.get('target')}_{summary.get('environment')}"
    if named and path.parent.name != want:
        raise InputError(
            path,
            "",
            f"the map of {want[:80]!r} is in the folder {path.parent.name[:80]!r}; a run's "
            "maps are named <target>_<environment> (move it to coverage/" + want[:80] + ")",
        )


def write_report(folder: Path) -> tuple[Path, Path]:
    """``report.html`` and ``report.md`` into the run folder."""
    title, meta, front, sections = build(Path(folder))
    html_path, md_path = Path(folder) / "report.html", Path(folder) / "report.md"
    atomic_write_text(html_path, render_html(title, meta, sections, front))
    atomic_write_text(md_path, render_markdown(title, meta, sections, front))
    return html_path, md_path
