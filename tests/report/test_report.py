"""The audit report: every section, table and image; self-contained; deterministic but for
its one timestamp; degrades when parts were not run (one line each, no printed page of its
own); size budget; A-vs-B. The summary page: tests/report/test_summary.py; what a browser
shows: tests/report/test_browser.py."""

from __future__ import annotations

import base64
import json
import re
import shutil
from pathlib import Path

import pytest
from lxml import html as lhtml

from sensorgap.cli import main

SECTIONS = [
    "summary",
    "vehicle",
    "nearfield",
    "coverage",
    "table-iv",
    "scenarios",
    "robustness",
    "anchors",
    "assumptions",
    "accuracy",
    "reproduce",
    "appendix",
]
#: report.html size budget (docs/report.md): per embedded figure (base64 bytes), for the
#: text without figures, and in all for the default job (35 figures).
FIGURE_BUDGET_B = 150_000
TEXT_BUDGET_B = 300_000
TOTAL_BUDGET_B = 2_500_000


def _doc(path: Path) -> lhtml.HtmlElement:
    return lhtml.fromstring(path.read_bytes())


def test_every_section_table_and_image(job: Path) -> None:
    doc = _doc(job / "report.html")
    assert [s.get("id") for s in doc.findall(".//body/section")] == SECTIONS
    for sid in SECTIONS:
        sec = doc.get_element_by_id(sid)
        assert sec is not None and sec.find("h2") is not None, sid
    for sid in (
        "nearfield",
        "coverage",
        "table-iv",
        "scenarios",
        "accuracy",
        "reproduce",
        "sensor-setup",
        "environments",
    ):
        tables = doc.get_element_by_id(sid).findall(".//table")
        assert tables, sid
        for t in tables:
            assert t.findall(".//tbody/tr"), f"empty table in {sid}"
    # the appendix lists every sensor; every physical parameter names a source, and where
    # the source is the out-of-repository physics.md the report says where it is
    setup = doc.get_element_by_id("sensor-setup")
    assert setup.getparent().get("id") == "appendix"
    assert len(setup.findall(".//table")[0].findall(".//tbody/tr")) == 23
    rows = setup.findall(".//table")[1].findall(".//tbody/tr")
    assert all(r.findall("td")[4].text_content().strip() for r in rows)
    if any("physics.md" in r.findall("td")[4].text_content() for r in rows):
        assert "shared/reference/physics.md" in setup.text_content()
    # the detailed sections carry no parameter-source table before the appendix
    assert not doc.get_element_by_id("vehicle").findall(".//table")
    imgs = doc.findall(".//img")
    ranked = json.loads((job / "ranking.json").read_text())["ranking"]
    assert len(imgs) >= 1 + 7 + 7 + len(ranked)  # near field, 7 maps, 7 far-field, scenarios
    for img in imgs:
        src = img.get("src")
        assert src.startswith("data:image/png;base64,")
        assert base64.b64decode(src.split(",", 1)[1])[:8] == b"\x89PNG\r\n\x1a\n"
        assert img.get("alt")


def test_self_contained_and_printable(job: Path) -> None:
    text = (job / "report.html").read_text()
    doc = _doc(job / "report.html")
    assert not doc.findall(".//script") and not doc.findall(".//link")
    assert not re.search(r"""(src|href)=["']?(https?:)?//""", text)
    assert "@media print" in text
    for a in doc.findall(".//a"):
        href = a.get("href")
        if not href.startswith("#"):
            assert (job / href).is_file(), href


def test_scenarios_link_their_files_and_say_why(job: Path) -> None:
    doc = _doc(job / "report.html")
    ranked = json.loads((job / "ranking.json").read_text())["ranking"]
    for r in ranked:
        sec = doc.get_element_by_id(f"scenario-{r['rank']}")
        hrefs = [a.get("href") for a in sec.findall(".//a")]
        assert f"scenarios/{r['scenario_id']}.xosc" in hrefs
        assert any(h.startswith("roads/") and h.endswith(".xodr") for h in hrefs)
        text = " ".join(sec.text_content().split())  # no-break spaces as spaces
        assert "Why critical (as the search recorded it): " + r["reason"] in text
        assert "In words: " in text


def test_markdown_has_the_same_content(job: Path) -> None:
    md = (job / "report.md").read_text()
    doc = _doc(job / "report.html")
    for h in doc.findall(".//h2") + doc.findall(".//h3"):
        title = h.text_content()
        if title != "Contents":
            assert title in md, title
    for target in re.findall(r"!\[[^\]]*\]\(([^)]+)\)", md):
        assert (job / target).is_file(), target


def test_deterministic_but_for_the_timestamp(
    job: Path, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    from sensorgap.report import write_report

    b = (job / "report.html").read_text()  # the job's own, at the time it ran
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")
    write_report(job)
    a = (job / "report.html").read_bytes()
    write_report(job)
    assert (job / "report.html").read_bytes() == a
    diff = [(x, y) for x, y in zip(a.decode().splitlines(), b.splitlines(), strict=True) if x != y]
    assert len(diff) == 1 and "Generated (UTC)" in diff[0][1]


def test_degrades_when_parts_were_not_run(search_only: Path) -> None:
    doc = _doc(search_only / "report.html")
    for sid in ("nearfield", "coverage", "table-iv"):
        sec = doc.get_element_by_id(sid)
        # one line, and no printed page of its own (print CSS: section.short)
        assert [p.text_content() for p in sec.findall("p")] == ["Not part of this run."]
        assert sec.get("class") == "top short"
    assert "Not exported" in doc.get_element_by_id("scenarios").text_content()
    assert "not exported" in doc.get_element_by_id("test-first").text_content()
    # sections with tables or figures do start a printed page
    assert doc.get_element_by_id("scenarios").get("class") == "top"


def test_size_budget(job: Path) -> None:
    """docs/report.md: each embedded figure <= 150 kB, the text <= 300 kB, the whole file
    <= 2.5 MB for the default job's 35 figures (this job has fewer scenario figures)."""
    text = (job / "report.html").read_text()
    figures = re.findall(r'src="data:image/png;base64,([^"]+)"', text)
    assert len(figures) >= 15  # maps, near and far field, the ranked scenarios
    assert max(len(f) for f in figures) <= FIGURE_BUDGET_B
    assert len(text) - sum(len(f) for f in figures) <= TEXT_BUDGET_B
    # the default job's 35 figures at this job's mean size stay within the total budget
    mean = sum(len(f) for f in figures) / len(figures)
    assert len(text) + (35 - len(figures)) * mean <= TOTAL_BUDGET_B
    # the embedded figures are the run's PNGs reduced to 256 colours, not the originals
    raw = (job / "nearfield" / "nearfield.png").read_bytes()
    assert base64.b64encode(raw).decode() not in text


def test_bad_files_are_one_line_exit_2(
    job: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "bad"
    shutil.copytree(job, bad)
    (bad / "nearfield" / "nearfield.json").write_text("{not json")
    assert main(["report", "--run", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert "nearfield.json" in err and len(err.splitlines()) == 1
    assert main(["report", "--run", str(tmp_path / "nope")]) == 2


def test_compare_a_vs_b(compared: Path) -> None:
    doc = _doc(compared / "report.html")
    near = doc.get_element_by_id("nearfield").text_content()
    assert "System A" in near and "System B" in near
    # issue #14 item 4: complete, although A's run holds a search only and B's a search
    # and a near field: their near field, coverage maps and far field are computed, a
    # difference map for every map
    assert "Not part of this run" not in doc.text_content()
    what = " ".join(doc.get_element_by_id("compared").text_content().split())
    assert "System A (A): run folder system_a; computed for this comparison" in what
    assert "System B (B): run folder system_b; computed for this comparison" in what
    for side in ("system_a", "system_b"):
        maps = sorted(p.name for p in (compared.parent / side).glob("*"))
        assert "coverage" not in maps and "farfield" not in maps  # run folders untouched
    assert (compared / "a_system_a" / "nearfield" / "nearfield.json").is_file()
    assert not (compared / "b_system_b" / "nearfield").exists()  # B's own is taken
    cov = doc.get_element_by_id("coverage")
    diff_dirs = sorted(p.name for p in (compared / "difference").iterdir())
    made = sorted(p.name for p in (compared / "a_system_a" / "coverage").iterdir())
    assert diff_dirs == made and "car_clear" in diff_dirs and "car_fog_50" in diff_dirs
    for d in diff_dirs:
        assert f"coverage {d}" in what  # computed for B
        assert cov.get_element_by_id(f"coverage-{d}") is not None
    assert len(cov.findall(".//img")) == len(diff_dirs)
    assert (compared / "b_system_b" / "farfield" / "fog_50" / "farfield.csv").is_file()
    assert doc.get_element_by_id("table-iv").findall(".//img")
    scen = doc.get_element_by_id("scenarios")
    assert scen.findall(".//table") and (compared / "comparison.csv").is_file()
    assert (compared / "report.md").is_file() and (compared / "manifest.json").is_file()
    # the cross-evaluation table holds numbers only; every scenario's why follows as a list
    table = scen.findall(".//table")[1]
    heads = [th.text_content() for th in table.findall(".//th")]
    assert "why" not in heads and len(heads) <= 13
    rows = table.findall(".//tbody/tr")
    assert len(scen.findall(".//li")) == len(rows) > 0


def test_compare_markdown_links_resolve(compared: Path) -> None:
    md = (compared / "report.md").read_text()
    targets = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", md)
    assert len(targets) >= 2
    for t in targets:
        assert " " not in t and (compared / t).is_file(), t


def test_anchor_cases_in_the_report(job: Path, search_only: Path) -> None:
    # issue #17: the default job evaluates the Euro NCAP obstructed crossing; the report
    # lists every test speed with the exact P(collision) and impact speed of
    # anchors/anchors.json (to the printed digits); a run without anchors says so in
    # one line
    rows = json.loads((job / "anchors" / "anchors.json").read_text())["anchors"]
    assert [round(r["vut_kmh"]) for r in rows] == [10, 20, 30, 40, 50, 60]
    md = (job / "report.md").read_text()
    part = md.split("## Anchor cases", 1)[1].split("\n## ", 1)[0]
    for r in rows:
        line = next(ln for ln in part.splitlines() if ln.startswith(f"| {r['vut_kmh']:.0f} | 5 |"))
        cells = [c.strip() for c in line.strip("|").split("|")]
        assert cells[2] == r["class"]
        assert cells[3] == format(r["collision_probability"], ".2g")
        assert cells[4] == format(r["impact_speed_kmh"], ".1f")
    assert "sensorgap evaluate --vehicle system_a --family pedestrian_behind_parked_cars" in part
    other = (search_only / "report.md").read_text().split("## Anchor cases", 1)[1]
    assert other.split("\n## ", 1)[0].strip().endswith("Not part of this run.")


@pytest.mark.parametrize("wide", [0.0, 1e9], ids=["map-above", "side-by-side"])
def test_scenario_figure_shows_the_named_step(
    job: Path, monkeypatch: pytest.MonkeyPatch, tmp_path: Path, wide: float
) -> None:
    # issue #14 item 6: the per-scenario figure draws the target's body at the step the
    # reason names (with its exact Pd of the confirming sensors), the scene's occluders
    # at that step, and over time the confirming Pd, P(confirmed), the path TTC and the
    # threat onset / t_safe / median confirmation of the ranking row
    from sensorgap.export.spec import read_run, specs_of_run
    from sensorgap.report import figures
    from sensorgap.search.evaluate import Evaluator
    from sensorgap.search.ranking import named_step

    run = read_run(job)
    spec = next(s for s in specs_of_run(run) if s.scenario.occluders)
    ev = Evaluator(spec.system, mode="exact")
    tr = figures.scenario_trace(spec, ev)
    # both layouts: the map above the curves (a long scene) and beside them
    monkeypatch.setattr(figures, "WIDE_SCENE", wide)
    fig = figures.draw_scenario_figure(spec, ev, tr)
    fig.canvas.draw()
    ax, bx = fig.axes[:2]
    pa, pb = ax.get_position(), bx.get_position()
    assert (pa.y0 > pb.y1) if wide == 0.0 else (pa.x1 < pb.x0)  # above / beside
    cbar = next(a for a in ax.child_axes if a.get_ylabel() == "$p_d$")
    pc = cbar.get_position()
    assert pc.height == pytest.approx(pa.height, rel=1e-6)  # as tall as the map
    labels = [t.get_text() for leg in fig.legends for t in leg.get_texts()]
    k = named_step(tr)
    pdc = tr.pd if tr.pd_confirm is None else tr.pd_confirm
    assert f"target at t = {tr.t[k]:.2f} s (Pd {pdc[k]:.2f})" in labels
    assert "occluders at that step" in labels
    assert any(lab.startswith("P(confirmed") for lab in labels)
    assert "path TTC [s] (cut at 10 s)" in labels
    assert {"threat onset", "t_safe"} <= set(labels)
    # the fixed layout: every axes with its labels, ticks, title (and the colour bar) and
    # both legends inside the figure, the legends clear of every axes' labels
    r = fig.canvas.get_renderer()
    whole = fig.bbox
    boxes = [a.get_tightbbox(r) for a in fig.axes]
    legends = [leg.get_window_extent(r) for leg in fig.legends]
    for b in boxes + legends:
        assert whole.x0 - 0.5 <= b.x0 and b.x1 <= whole.x1 + 0.5, (b, whole)
        assert whole.y0 - 0.5 <= b.y0 and b.y1 <= whole.y1 + 0.5, (b, whole)
    for leg in legends:
        for b in boxes:
            assert not leg.overlaps(b), (leg, b)


def test_markdown_shows_names_as_written_not_as_html() -> None:
    """report.md: text a Markdown renderer would take for HTML (a family file named
    ``st op&<x>``, the report's own ``difference/<map>/``) is written with entities that
    show it as written; ``Pd < 0.5`` and plain ``&`` stay as they are."""
    from sensorgap.report.document import Bullets, Link, Para, Section, Table, render_markdown

    sec = Section(
        "s",
        "From st op&<x>",
        [
            Para("The ranked scenarios come from st op&<x> (1); Pd < 0.5 & more."),
            Bullets([("<b>bold</b>", "&amp; &#60;")]),
            Table(["family"], [["st op&<x>"], [Link("<x>", "x.html")]], "maps: difference/<map>/"),
        ],
    )
    md = render_markdown("Report <i>", ["run <script>"], [sec])
    assert "<x>" not in md and "<map>" not in md and "<b>" not in md and "<i>" not in md
    assert "<script>" not in md
    assert "st op&&lt;x> (1); Pd < 0.5 & more." in md
    assert "difference/&lt;map>/" in md and "&amp;amp; &amp;#60;" in md
    assert "[&lt;x>](x.html)" in md


def test_a_run_made_with_other_software_says_so(
    search_only: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A run whose run.json records another sensorgap version (hostile round eight: the
    report showed 9.9.9 and said nothing, while it rebuilt its figures with this code): the
    versions table has both columns and a paragraph names what differs."""
    from sensorgap.filesio import write_manifest

    run = tmp_path / "run"
    shutil.copytree(search_only, run)
    info = json.loads((run / "run.json").read_text(encoding="utf-8"))
    info["versions"]["sensorgap"] = "9.9.9"
    (run / "run.json").write_text(json.dumps(info, indent=2), encoding="utf-8")
    write_manifest(run)
    assert main(["report", "--run", str(run)]) == 0, capsys.readouterr().err
    text = _doc(run / "report.html").get_element_by_id("reproduce").text_content()
    assert "9.9.9" in text
    assert "The run was made with other software than this report (sensorgap)" in text
    own = _doc(search_only / "report.html").get_element_by_id("reproduce").text_content()
    assert "other software" not in own


def test_what_a_report_shows_of_a_run_is_bounded_and_checked_where_it_is_used(
    job: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Hostile round 26: 64 valid figures of 19 MB each took a report to 5.4 GB (the
    figures a run shows are bounded in all: ``MAX_RUN_FIGURE_BYTES``), and a near field
    replaced after ``check_pieces`` was printed unchecked by the comparison (the values
    printed are read through the same checks where they are used)."""
    import shutil

    from sensorgap.errors import InputError
    from sensorgap.report import build

    sizes = [
        p.stat().st_size
        for p in (
            *job.glob("nearfield/nearfield.png"),
            *job.glob("coverage/*/coverage.png"),
            *job.glob("farfield/*/farfield.png"),
        )
    ]
    build.check_pieces(job, "System A")  # within the bounds as shipped
    monkeypatch.setattr(build, "MAX_RUN_FIGURE_BYTES", sum(sizes) - 1)
    with pytest.raises(InputError, match=r"its figures to show exceed \d+ bytes in all \(at "):
        build.check_pieces(job, "System A")
    monkeypatch.undo()
    nf = tmp_path / "nearfield" / "nearfield.json"
    nf.parent.mkdir()
    shutil.copyfile(job / "nearfield" / "nearfield.json", nf)
    assert build.checked_nearfield(nf, "System A")["system"] == "System A"
    with pytest.raises(InputError, match="'System A' is not this run's vehicle"):
        build.checked_nearfield(nf, "System B")
    nf.write_text(nf.read_text().replace('"exact": ', '"exact": NaN, "x": ', 1))
    with pytest.raises(InputError, match="blind_spot_m2.exact: expected a number, got nan"):
        build.checked_nearfield(nf, "System A")


def test_a_run_folder_named_with_control_characters_is_written_escaped(
    search_only: Path, tmp_path: Path
) -> None:
    """Hostile round 35: a run folder named ``q<ESC>[2Jz`` reached report.md and
    report.html raw (``cat report.md`` cleared the terminal), in "Run folder:" and, unquoted,
    in "Reproduce with:". Every text of a report is written with control and format
    characters escaped (``errors.escape_controls``) and the command line shell-quoted."""
    from sensorgap.errors import escape_controls

    assert escape_controls("a\x1b[2J\u202eb\n\tc\u00a0m") == "a\\x1b[2J\\u202eb\n\tc\u00a0m"
    run = tmp_path / "q\x1b[2Jz x;y"
    shutil.copytree(search_only, run)
    info = json.loads((run / "run.json").read_text(encoding="utf-8"))
    assert main(["report", "--run", str(run)]) == 0
    for name in ("report.md", "report.html"):
        data = (run / name).read_bytes()
        assert not re.search(rb"[\x00-\x08\x0b-\x1f\x7f]", data), name
        assert b"\xe2\x80\xae" not in data, name  # no U+202E either
    md = (run / "report.md").read_text(encoding="utf-8")
    assert "Run folder: q\\x1b[2Jz x;y." in md
    line = next(ln for ln in md.splitlines() if ln.startswith("Reproduce with: "))
    # a search run through the library records no command: the line is the report's own
    assert info.get("command") is None
    # bash's $'...' gives the ESC back when the line is pasted (shlex's '...' did not)
    assert line.endswith(" $'" + str(run).replace("\x1b", "\\x1b") + "'"), line


def test_shell_quote_gives_back_what_a_shell_reads() -> None:
    """The "Reproduce with" line of a run folder whose name is not valid UTF-8 showed
    ``\\udcff``, which no shell reads back (remark of session 25). ``errors.shell_quote``
    writes such bytes, and control characters, as bash's ``$'\\xNN'``; bash itself reads
    each quoted word back to the same bytes."""
    import os
    import subprocess

    from sensorgap.errors import shell_join, shell_quote

    words = [os.fsdecode(b"/tmp/a\xffb"), "x\x1b[2J", "a b'c", "\u00e9t\u00e9", "plain", "\\"]
    assert shell_quote(words[0]) == "$'/tmp/a\\xffb'"
    assert shell_quote(words[4]) == "plain"
    out = subprocess.run(
        ["bash", "-c", "printf '%s\\0' " + shell_join(words)], capture_output=True, check=True
    ).stdout
    assert out.split(b"\0")[:-1] == [os.fsencode(w) for w in words]


def test_a_file_given_as_the_run_is_said_to_be_one(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Hostile round 35 (a remark): ``report --run FILE`` said "run folder does not
    exist" of a file that exists; it says what it is, and a missing one is still missing."""
    afile = tmp_path / "run.txt"
    afile.write_text("x", encoding="utf-8")
    assert main(["report", "--run", str(afile)]) == 2
    assert capsys.readouterr().err.strip().endswith("run.txt: is not a folder: give a run folder")
    assert main(["report", "--run", str(tmp_path / "nope")]) == 2
    assert capsys.readouterr().err.strip().endswith("nope: run folder does not exist")
