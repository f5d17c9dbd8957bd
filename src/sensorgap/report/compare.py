"""``sensorgap compare RUN_A RUN_B`` and ``sensorgap report --compare RUN_A RUN_B``: two
vehicles side by side (the paper's A-vs-B view), always complete: what either run folder
lacks (near field, coverage maps, far field) is computed from that run's recorded inputs
first (``search.compare_maps``). Sections: what is compared (and what was computed), the
near-field blind spots, the coverage maps of both vehicles on one grid with their
difference map (where one detects and the other does not), Table IV with Pd against
distance, and which critical scenarios are critical for one vehicle and not the other
(cross-evaluated, with the reason traced to the two sensor setups).

Layout: the cross-evaluation table holds the numbers only (11 short columns, readable in a
1280 px window); each scenario's explanation follows as a list. Figures from the run folders
are copied beside the report as ``a_<vehicle>_...`` / ``b_<vehicle>_...`` with the vehicle
name reduced to letters, digits, ``.``, ``_`` and ``-`` (Markdown links without spaces; two
runs of vehicles with the same name do not overwrite each other's figures). Two vehicles of
the same name (two versions of one vehicle file) are told apart everywhere by their tag and
run folder, ``System B (A: run1)`` and ``System B (B: run2)`` (``search.compare.side_labels``:
columns, ``critical_for``, headings and text); figures made
for the comparison are linked where they were written (``difference/<map>/``,
``a_<vehicle>/``, ...)."""

from __future__ import annotations

import math
import os
from collections import Counter
from pathlib import Path

import numpy as np

from sensorgap.analysis.paper import FarFieldSetup
from sensorgap.atomic import atomic_write_bytes, atomic_write_text
from sensorgap.config.presets import shipped_road
from sensorgap.errors import InputError
from sensorgap.filesio import MANIFEST_NAME, not_a_run_folder, read_manifest, remove_outputs
from sensorgap.provenance import utc_now
from sensorgap.report.build import (
    check_pieces,
    checked_map_summary,
    checked_nearfield,
    fmt,
    read_csv,
    read_json,
)
from sensorgap.report.document import (
    Block,
    Bullets,
    Image,
    Para,
    Section,
    Table,
    render_html,
    render_markdown,
)
from sensorgap.report.figures import farfield_pair_figure
from sensorgap.search.compare import MARGIN_P, run_notes, write_comparison
from sensorgap.search.compare_maps import DETECTS_PD, Completed, SideMaps, complete_runs, slug
from sensorgap.search.runfolder import open_run

__all__ = ["slug", "write_compare_report"]

LEVELS = ("pd=1.0", "pd>=0.8", "pd>=0.5", "pd>0", "pd=0")


def _m2(v: object) -> str:
    """An area (m2) of a map: whole square metres with thousands separators (the maps'
    cells are 0.25 m2 or more), below 10 m2 to two decimals."""
    if isinstance(v, bool) or not isinstance(v, int | float):
        return ""
    return f"{v:,.0f}" if abs(v) >= 10 else f"{v:.2f}"


def _unmade(side: SideMaps, what: str) -> Para:
    """Why a piece of one vehicle is missing (it could not be computed)."""
    return Para(
        f"{what} of {side.name}: cannot be computed (the run folder "
        f"{side.run.folder.name} records no vehicle)."
    )


def _none_in_common(
    cm: Completed, anchor: str, title: str, lacking: list[SideMaps], what: str, thing: str
) -> Section:
    """A section with nothing to compare: why each side ``lacking`` the piece could not
    compute it (``_unmade``), or, when both have some, the comparison's notes."""
    blocks: list[Block] = [_unmade(s, what) for s in lacking]
    return Section(
        anchor, title, blocks or [Para(f"No {thing} in common: " + "; ".join(cm.notes) + ".")]
    )


def _where(side: SideMaps, folder: Path | None) -> str:
    """'from the run ...' or 'computed for this comparison' for a piece's folder."""
    if folder is None:
        return ""
    return (
        "computed for this comparison"
        if side.made in folder.parents
        else f"from the run {side.run.folder.name}"
    )


def _image(
    path: Path, caption: str, out: Path, tag: str, side: SideMaps | None, name: str
) -> Image:
    """An image; the file report.md links lies under ``out`` (where it was made, else a
    copy named ``<tag>_<vehicle>_<name>``)."""
    try:
        return Image(path, caption, path.resolve().relative_to(out.resolve()).as_posix())
    except ValueError:
        who = "" if side is None else f"{slug(side.name)}_"
        return Image(path, caption, f"{tag}_{who}{name}")


def _compared(cm: Completed) -> Section:
    items: list[str | tuple[str, str]] = []
    for side in (cm.a, cm.b):
        if side.computed:
            text = (
                f"run folder {side.run.folder.name}; computed for this comparison "
                "from the run's recorded inputs (vehicle, environments, target "
                f"classes): {', '.join(side.computed)} (in {side.made.name}/)."
            )
        elif not side.coverage and side.nearfield is None:
            text = (
                f"run folder {side.run.folder.name}; it records no vehicle: nothing "
                "could be computed."
            )
        else:
            text = (
                f"run folder {side.run.folder.name}; near field, coverage maps and far "
                "field all from the run (nothing computed)."
            )
        tag = side.tag.upper()  # a label of two same-named vehicles holds its tag already
        head = side.name if f"({tag}: " in side.name else f"{side.name} ({tag})"
        items.append((f"{head}:", text))
    items += [("Note:", n + ".") for n in cm.notes]
    # a search's own note (no feasible candidate: its empty ranking says nothing of the
    # sensors), so empty tables below are not read as "no gap in either"
    items += [("Note of run", n) for n in run_notes(cm.a.run.folder, cm.b.run.folder)]
    return Section(
        "compared",
        "What is compared",
        [
            Para(
                "Both vehicles in the same environments on the same grids: what a run folder "
                "lacks (near field, coverage maps, far field) is computed from that run's "
                "recorded inputs, never from a shipped preset of the same name."
            ),
            Bullets(items),
        ],
    )


def _vehicle(side: SideMaps) -> str | None:
    """The vehicle a side's pieces must be of (None: its run records none)."""
    try:
        return side.run.system().name
    except InputError:
        return None


def _nearfield(cm: Completed, out: Path) -> Section:
    a, b = cm.a, cm.b
    title = "Near-field blind spots"
    if a.nearfield is None or b.nearfield is None:
        return Section(
            "nearfield",
            title,
            [_unmade(s, "The near field") for s in (a, b) if s.nearfield is None],
        )
    vals: dict[str, tuple[float, float]] = {}
    unseen: dict[str, float] = {}
    imgs: list[Block] = []
    for side in (a, b):
        folder = side.nearfield
        assert folder is not None
        d = checked_nearfield(folder / "nearfield.json", _vehicle(side))  # as it is used
        try:
            vals[side.tag] = (
                float(d["blind_spot_m2"]["exact"]),
                float(d["uncovered_0p1m_m2"]["exact"]),
            )
            if "unseen_any_height_m2" in d:  # (runs made before it was written lack it)
                unseen[side.tag] = float(d["unseen_any_height_m2"]["exact"])
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(
                folder / "nearfield.json", "blind_spot_m2.exact", f"unreadable: {exc}"
            ) from None
        png = folder / "nearfield.png"
        if png.is_file():
            imgs.append(
                _image(
                    png,
                    f"{side.name}: near-field coverage ({_where(side, folder)})",
                    out,
                    side.tag,
                    side,
                    "nearfield.png",
                )
            )
    na, nb = a.name, b.name
    rows = [
        [
            "blind spot: enclosed, no sensor at any height (paper Fig. 5) [m2]",
            fmt(vals["a"][0]),
            fmt(vals["b"][0]),
            fmt(vals["b"][0] - vals["a"][0]),
        ],
    ]
    if len(unseen) == 2:
        rows.append(
            [
                "no sensor at any height, in all (enclosed and open to the outside) [m2]",
                fmt(unseen["a"]),
                fmt(unseen["b"]),
                fmt(unseen["b"] - unseen["a"]),
            ]
        )
    rows += [
        [
            "uncovered at 0.1 m [m2]",
            fmt(vals["a"][1]),
            fmt(vals["b"][1]),
            fmt(vals["b"][1] - vals["a"][1]),
        ],
    ]
    return Section("nearfield", title, [Table(["quantity", na, nb, f"{nb} - {na}"], rows), *imgs])


def _coverage(cm: Completed, out: Path) -> Section:
    a, b = cm.a, cm.b
    title = "Coverage maps side by side and their difference"
    if not cm.keys:
        lacking = [s for s in (a, b) if not s.coverage]
        return _none_in_common(cm, "coverage", title, lacking, "The coverage maps", "coverage map")
    na, nb = a.name, b.name
    rows = []
    for k in cm.keys:
        sa, sb = (
            checked_map_summary(
                s.coverage[k] / "summary.json", _vehicle(s), s.made not in s.coverage[k].parents
            ).get("area_m2_by_level", {})
            for s in (a, b)
        )
        for lv in LEVELS:
            va, vb = sa.get(lv), sb.get(lv)
            rows.append(
                [k, lv, _m2(va), _m2(vb), _m2(None if va is None or vb is None else vb - va)]
            )
    diff_rows, subs = [], []
    for k in cm.keys:
        if k not in cm.differences:
            continue
        d = read_json(cm.differences[k] / "summary.json")
        ar = d.get("area_m2", {})
        diff_rows.append(
            [k, *(_m2(ar.get(f)) for f in ("only_a_m2", "only_b_m2", "both_m2", "neither_m2"))]
        )
        png = cm.differences[k] / "difference.png"
        if png.is_file():
            subs.append(
                Section(
                    f"coverage-{slug(k)}",
                    k,
                    [
                        _image(
                            png,
                            f"{k}: A {_where(a, a.coverage[k])}, B {_where(b, b.coverage[k])}; "
                            "difference Pd_A - Pd_B",
                            out,
                            "difference",
                            None,
                            f"{slug(k)}.png",
                        )
                    ],
                )
            )
    return Section(
        "coverage",
        title,
        [
            Para(
                f"Each figure: the fused Pd of a car body of {na} (A, top) and {nb} (B, middle) "
                "on one grid in one environment, each with its sensors' fields of view and a "
                "near-field close-up, and the difference map Pd_A - Pd_B (bottom; blue: A "
                "detects where B does not, red: the reverse) with both vehicles' sensor "
                "positions."
            ),
            Table(
                [
                    "map",
                    f"only {na} detects [m2]",
                    f"only {nb} detects [m2]",
                    "both [m2]",
                    "neither [m2]",
                ],
                diff_rows,
                f"Where one vehicle detects (Pd >= {DETECTS_PD:g}) and the other does not "
                "(difference maps, difference/<map>/)",
            ),
            Table(
                ["map", "level", f"{na} [m2]", f"{nb} [m2]", f"{nb} - {na} [m2]"],
                rows,
                "Area per Pd level",
            ),
        ],
        subs,
    )


def _farfield_levels(folder: Path) -> dict[str, float]:
    """The lengths (m) per detection level of a far field's ``summary.json``: an object of
    finite numbers >= 0, else ``InputError`` naming the file (hostile round 24: a list was
    an internal error, NaN printed as "nan")."""
    path = folder / "summary.json"
    d = read_json(path)
    levels = d.get("levels_m", {}) if isinstance(d, dict) else None
    if not isinstance(levels, dict):
        raise InputError(path, "levels_m", "expected a JSON object of lengths (m) per level")
    out = {}
    for k, v in levels.items():
        if isinstance(v, bool) or not isinstance(v, int | float) or not (0.0 <= v < math.inf):
            raise InputError(
                path, f"levels_m.{str(k)[:40]}", f"expected a length >= 0 (m), got {str(v)[:40]!r}"
            )
        out[str(k)] = float(v)
    return out


def _profile(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(distance s, fused Pd) of a far-field ``farfield.csv``: each s a finite length
    >= 0 (m), increasing row by row, each pd within 0..1; else ``InputError`` naming the
    row and column (hostile round 25: NaN, negative distances and a Pd of 5 were
    plotted)."""
    rows = read_csv(path)
    s_m, pd = np.zeros(len(rows)), np.zeros(len(rows))
    last = -math.inf
    for i, r in enumerate(rows):
        for col, out, lo, hi in (("s", s_m, 0.0, math.inf), ("pd", pd, 0.0, 1.0)):
            try:
                v = float(r[col])
            except (KeyError, TypeError, ValueError):
                v = math.nan
            if not (lo <= v <= hi and math.isfinite(v)):
                want = "a length >= 0 (m)" if col == "s" else "a probability 0..1"
                raise InputError(
                    path, f"row {i + 2}.{col}", f"expected {want}, got {str(r.get(col))[:40]!r}"
                )
            out[i] = v
        if s_m[i] <= last:
            raise InputError(path, f"row {i + 2}.s", "distances must increase row by row")
        last = s_m[i]
    return s_m, pd


def _table_iv(cm: Completed, out: Path) -> Section:
    a, b = cm.a, cm.b
    title = "Table IV (metres of the lane ahead) and Pd against distance"
    envs = [e for e in cm.environments if e in a.farfield and e in b.farfield]
    if not envs:
        lacking = [s for s in (a, b) if not s.farfield]
        return _none_in_common(cm, "table-iv", title, lacking, "The far field", "far field")
    na, nb = a.name, b.name
    rows, curves = [], []
    for e in envs:
        la, lb = _farfield_levels(a.farfield[e]), _farfield_levels(b.farfield[e])
        for lv in LEVELS:
            va, vb = la.get(lv), lb.get(lv)
            rows.append(
                [
                    e,
                    lv,
                    "" if va is None else f"{va:.1f}",
                    "" if vb is None else f"{vb:.1f}",
                    "" if va is None or vb is None else f"{vb - va:+.1f}",
                ]
            )
        curves.append(
            (
                e,
                *_profile(a.farfield[e] / "farfield.csv"),
                *_profile(b.farfield[e] / "farfield.csv"),
            )
        )
    png = farfield_pair_figure(curves, na, nb, out / "farfield_pd_vs_distance.png")
    where = "; ".join(
        f"{s.name}: " + ", ".join(sorted({_where(s, s.farfield[e]) for e in envs})) for s in (a, b)
    )
    return Section(
        "table-iv",
        title,
        [
            Para(
                "Length (m) of the car path in the right lane of motorway_r500 ahead of the ego "
                "(left lane, 50 m before the clothoid into the R = 500 m curve) at each "
                f"detection level, as in the paper's Table IV ({where})."
            ),
            Table(["environment", "level", f"{na} [m]", f"{nb} [m]", f"{nb} - {na} [m]"], rows),
            Image(
                png,
                "Fused Pd of a car body along the right lane against the distance from "
                f"the front bumper: {na} (A, solid) and {nb} (B, dashed) per environment",
                png.name,
            ),
        ],
    )


def _scenarios(a: Path, b: Path, out: Path) -> Section:
    missing = [f.name for f in (a, b) if not (f / "ranking.json").is_file()]
    if missing:
        return Section(
            "scenarios",
            "Critical for one, not the other",
            [
                Para(
                    f"No search in {' and '.join(missing)} (ranking.json): the cross-evaluation of "
                    "critical scenarios needs a search of both vehicles (`sensorgap search --out "
                    "RUN` or `sensorgap run`)."
                )
            ],
        )
    rows = write_comparison(a, b, out)
    counts = Counter((str(r["critical_for"]), str(r["dominant_effect"])) for r in rows)
    cols = [("scenario_id", "scenario"), ("family", "family"), ("environment", "environment")]
    names = [k[len("rank_") :] for k in rows[0] if k.startswith("rank_")] if rows else []
    for key, head in (
        ("rank", "rank"),
        ("collision_probability", "P(collision)"),
        ("impact_speed_kmh", "impact [km/h]"),
        ("class", "class"),
    ):
        cols += [(f"{key}_{n}", f"{head} {n}") for n in names]
    cols += [("critical_for", "critical for"), ("dominant_effect", "dominant effect")]

    def cell(key: str, v: object) -> str:
        if key.startswith("impact_speed_kmh") and isinstance(v, int | float):
            return f"{v:.0f}"
        if key.startswith("class_"):
            return str(v or "")
        return fmt(v, 2) if isinstance(v, float) else fmt(v)

    return Section(
        "scenarios",
        "Critical for one, not the other",
        [
            Para(
                "Every scenario ranked for either vehicle, evaluated exactly for both. Critical "
                f"for one vehicle only: its collision probability higher by at least {MARGIN_P:g}."
            ),
            Table(
                ["critical for", "dominant effect", "scenarios"],
                [[w, e, str(n)] for (w, e), n in sorted(counts.items())],
                "Summary",
            ),
            Table(
                [h for _, h in cols],
                [[cell(k, r.get(k)) for k, _ in cols] for r in rows],
                "Cross-evaluation (comparison.csv; why: below)",
            ),
            Bullets(
                [
                    (f"{r['scenario_id']} (critical for {r['critical_for']}):", str(r["why"]))
                    for r in rows
                ]
            ),
        ],
    )


def clear_earlier_comparison(out: Path) -> list[str]:
    """A rerun into its own earlier comparison (the CLI refuses any other certified
    folder): the files the earlier one's manifest lists are removed first, so the folder
    then holds only this comparison's (hostile round 26: the earlier pieces, such as a
    near field computed before the run had its own, stayed beside the new ones,
    certified); a file of the user's, which the manifest does not list, is kept. Returns
    the removed files' relative paths."""
    if not (out / MANIFEST_NAME).is_file():
        return []
    earlier = read_manifest(out)
    if "comparison.json" not in earlier:
        return []
    return remove_outputs(out, tuple(rel for rel in earlier if rel != MANIFEST_NAME))


def write_compare_report(
    run_a: Path, run_b: Path, out: Path, workers: int = 2
) -> tuple[Path, Path]:
    """``out/report.html`` and ``out/report.md`` comparing two run folders; what either run
    lacks is computed into ``out`` first (``search.compare_maps.complete_runs``)."""
    run_a, run_b = Path(run_a), Path(run_b)
    for f in (run_a, run_b):
        if not f.is_dir():
            raise InputError(f, "", not_a_run_folder(f))
    for f in (run_a, run_b):  # what the comparison shows of each run, before any work
        try:
            vehicle: str | None = open_run(f, ranking=False).system().name
        except InputError:
            vehicle = None  # not recorded: nothing is computed for it (complete_runs)
        check_pieces(f, vehicle)
    if os.environ.get("SENSORGAP_ROADS"):  # the far field's road, before any work
        shipped_road(FarFieldSetup().road)
    out = Path(out)
    clear_earlier_comparison(out)
    out.mkdir(parents=True, exist_ok=True)
    cm = complete_runs(run_a, run_b, out, workers=workers)
    sections = [
        _compared(cm),
        _nearfield(cm, out),
        _coverage(cm, out),
        _table_iv(cm, out),
        _scenarios(run_a, run_b, out),
    ]
    for s in sections:  # Markdown links the PNGs next to the report
        for blk in [*s.blocks, *(x for sub in s.subsections for x in sub.blocks)]:
            if isinstance(blk, Image) and blk.path.resolve() != (out / blk.rel).resolve():
                atomic_write_bytes(out / blk.rel, blk.path.read_bytes())
    title = f"sensorgap: {cm.a.name} vs {cm.b.name}"
    meta = [f"Runs: {run_a.name} and {run_b.name}.", f"Generated (UTC): {utc_now()}"]
    html_path, md_path = out / "report.html", out / "report.md"
    atomic_write_text(html_path, render_html(title, meta, sections))
    atomic_write_text(md_path, render_markdown(title, meta, sections))
    return html_path, md_path
