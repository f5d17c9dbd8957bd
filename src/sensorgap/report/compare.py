"""``sensorgap report --compare RUN_A RUN_B``: two vehicles side by side (the paper's A-vs-B
view): blind spots, coverage per Pd level and environment, Table IV, and which critical
scenarios are critical for one vehicle and not the other (cross-evaluated, with the reason
traced to the two sensor setups).

Layout: the cross-evaluation table holds the numbers only (11 short columns, readable in a
1280 px window); each scenario's explanation follows as a list. Figures copied beside the
report are named ``a_<vehicle>_...`` / ``b_<vehicle>_...`` with the vehicle name reduced to
letters, digits, ``.``, ``_`` and ``-`` (Markdown links without spaces; two runs of
vehicles with the same name do not overwrite each other's figures)."""

from __future__ import annotations

import re
from collections import Counter
from pathlib import Path

from sensorgap.atomic import atomic_write_bytes, atomic_write_text
from sensorgap.errors import InputError
from sensorgap.provenance import utc_now
from sensorgap.report.build import NOT_RUN, fmt, read_csv, read_json
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
from sensorgap.search.compare import MARGIN_P, write_comparison
from sensorgap.search.runfolder import open_run

LEVELS = ("pd=1.0", "pd>=0.8", "pd>=0.5", "pd>0", "pd=0")


def _name(folder: Path) -> str:
    """The vehicle's name as the run recorded it (the folder's name when it has none)."""
    try:
        return open_run(folder, ranking=False).system().name
    except InputError:
        return folder.name


def slug(name: str) -> str:
    """A vehicle name as a file-name part (no spaces)."""
    return re.sub(r"[^A-Za-z0-9._-]+", "_", name).strip("_").lower() or "vehicle"


def _nearfield(a: Path, b: Path, na: str, nb: str) -> Section:
    rows, imgs = [], []
    vals = {}
    for tag, name, folder in (("a", na, a), ("b", nb, b)):
        p = folder / "nearfield" / "nearfield.json"
        if p.is_file():
            d = read_json(p)
            vals[name] = (d["blind_spot_m2"]["exact"], d["uncovered_0p1m_m2"]["exact"])
            png = folder / "nearfield" / "nearfield.png"
            if png.is_file():
                imgs.append(Image(png, f"{name}: near-field coverage",
                                  f"{tag}_{slug(name)}_nearfield.png"))
    if len(vals) < 2:
        return Section("nearfield", "Near-field blind spots", [Para(NOT_RUN)])
    rows.append(["blind spot (no sensor at any height) [m2]", fmt(vals[na][0]),
                 fmt(vals[nb][0]), fmt(vals[nb][0] - vals[na][0])])
    rows.append(["uncovered at 0.1 m [m2]", fmt(vals[na][1]), fmt(vals[nb][1]),
                 fmt(vals[nb][1] - vals[na][1])])
    blocks: list[Block] = [Table(["quantity", na, nb, f"{nb} - {na}"], rows), *imgs]
    return Section("nearfield", "Near-field blind spots", blocks)


def _coverage(a: Path, b: Path, na: str, nb: str) -> Section:
    def areas(folder: Path) -> dict[str, dict[str, float]]:
        out = {}
        for d in sorted((folder / "coverage").glob("*/summary.json")):
            out[d.parent.name] = read_json(d).get("area_m2_by_level", {})
        return out

    aa, bb = areas(a), areas(b)
    common = [k for k in aa if k in bb]
    if not common:
        return Section("coverage", "Coverage per Pd level", [Para(NOT_RUN)])
    rows = []
    for k in common:
        for lv in LEVELS:
            va, vb = aa[k].get(lv), bb[k].get(lv)
            rows.append([k, lv, fmt(va), fmt(vb),
                         fmt(None if va is None or vb is None else vb - va)])
    blocks: list[Block] = [Table(["map", "level", f"{na} [m2]", f"{nb} [m2]",
                                  f"{nb} - {na} [m2]"], rows, "Area per Pd level")]
    for k in common[:2]:
        for tag, name, folder in (("a", na, a), ("b", nb, b)):
            png = folder / "coverage" / k / "coverage.png"
            if png.is_file():
                blocks.append(Image(png, f"{name}: {k}", f"{tag}_{slug(name)}_{k}.png"))
    return Section("coverage", "Coverage per Pd level", blocks)


def _table_iv(a: Path, b: Path, na: str, nb: str) -> Section:
    pa, pb = a / "farfield" / "table_iv.csv", b / "farfield" / "table_iv.csv"
    if not (pa.is_file() and pb.is_file()):
        return Section("table-iv", "Table IV (metres of the lane ahead)", [Para(NOT_RUN)])
    va = {(r["environment"], r["level"]): r["metres"] for r in read_csv(pa)}
    vb = {(r["environment"], r["level"]): r["metres"] for r in read_csv(pb)}
    rows = [[e, lv, va[(e, lv)], vb.get((e, lv), "")] for (e, lv) in va]
    return Section("table-iv", "Table IV (metres of the lane ahead)",
                   [Table(["environment", "level", na, nb], rows)])


def _scenarios(a: Path, b: Path, out: Path) -> Section:
    if not ((a / "ranking.json").is_file() and (b / "ranking.json").is_file()):
        return Section("scenarios", "Critical for one, not the other", [Para(NOT_RUN)])
    rows = write_comparison(a, b, out)
    counts = Counter((str(r["critical_for"]), str(r["dominant_effect"])) for r in rows)
    cols = [("scenario_id", "scenario"), ("family", "family"),
            ("environment", "environment")]
    names = [k[len("rank_"):] for k in rows[0] if k.startswith("rank_")] if rows else []
    for key, head in (("rank", "rank"), ("collision_probability", "P(collision)"),
                      ("impact_speed_kmh", "impact [km/h]"), ("class", "class")):
        cols += [(f"{key}_{n}", f"{head} {n}") for n in names]
    cols += [("critical_for", "critical for"), ("dominant_effect", "dominant effect")]

    def cell(key: str, v: object) -> str:
        if key.startswith("impact_speed_kmh") and isinstance(v, int | float):
            return f"{v:.0f}"
        if key.startswith("class_"):
            return str(v or "")
        return fmt(v, 2) if isinstance(v, float) else fmt(v)

    return Section("scenarios", "Critical for one, not the other", [
        Para("Every scenario ranked for either vehicle, evaluated exactly for both. Critical "
             f"for one vehicle only: its collision probability higher by at least {MARGIN_P:g}."),
        Table(["critical for", "dominant effect", "scenarios"],
              [[w, e, str(n)] for (w, e), n in sorted(counts.items())], "Summary"),
        Table([h for _, h in cols], [[cell(k, r.get(k)) for k, _ in cols] for r in rows],
              "Cross-evaluation (comparison.csv; why: below)"),
        Bullets([(f"{r['scenario_id']} (critical for {r['critical_for']}):", str(r["why"]))
                 for r in rows]),
    ])


def write_compare_report(run_a: Path, run_b: Path, out: Path) -> tuple[Path, Path]:
    """``out/report.html`` and ``out/report.md`` comparing two run folders."""
    run_a, run_b = Path(run_a), Path(run_b)
    for f in (run_a, run_b):
        if not f.is_dir():
            raise InputError(f, "", "run folder does not exist")
    na, nb = _name(run_a), _name(run_b)
    out.mkdir(parents=True, exist_ok=True)
    sections = [_nearfield(run_a, run_b, na, nb), _coverage(run_a, run_b, na, nb),
                _table_iv(run_a, run_b, na, nb), _scenarios(run_a, run_b, out)]
    for s in sections:  # Markdown links the PNGs next to the report
        for blk in s.blocks:
            if isinstance(blk, Image):
                atomic_write_bytes(out / blk.rel, blk.path.read_bytes())
    title = f"sensorgap: {na} vs {nb}"
    meta = [f"Runs: {run_a.name} and {run_b.name}.", f"Generated (UTC): {utc_now()}"]
    html_path, md_path = out / "report.html", out / "report.md"
    atomic_write_text(html_path, render_html(title, meta, sections))
    atomic_write_text(md_path, render_markdown(title, meta, sections))
    return html_path, md_path
