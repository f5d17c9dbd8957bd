"""The audit report: every section, table and image; self-contained; deterministic but for
its one timestamp; degrades when parts were not run; A-vs-B; headless Chromium."""

from __future__ import annotations

import base64
import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest
from lxml import html as lhtml

from sensorgap.cli import main
from sensorgap.jobs import run_default
from sensorgap.search.run import run_search

SECTIONS = ["vehicle", "environments", "nearfield", "coverage", "table-iv", "scenarios",
            "assumptions", "accuracy", "reproduce"]


@pytest.fixture(scope="module")
def job(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("job")
    run_default(out, budget=1400, top=4)
    return out / "system_a"


def _doc(path: Path) -> lhtml.HtmlElement:
    return lhtml.fromstring(path.read_bytes())


def test_every_section_table_and_image(job: Path) -> None:
    doc = _doc(job / "report.html")
    for sid in SECTIONS:
        sec = doc.get_element_by_id(sid)
        assert sec is not None and sec.find("h2") is not None, sid
    for sid in ("vehicle", "environments", "nearfield", "coverage", "table-iv", "scenarios",
                "accuracy", "reproduce"):
        tables = doc.get_element_by_id(sid).findall(".//table")
        assert tables, sid
        for t in tables:
            assert t.findall(".//tbody/tr"), f"empty table in {sid}"
    # the vehicle table lists every sensor; every physical parameter names a source
    rows = doc.get_element_by_id("vehicle").findall(".//table")[1].findall(".//tbody/tr")
    assert all(r.findall("td")[4].text_content().strip() for r in rows)
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
        assert "Why critical:" in sec.text_content()


def test_markdown_has_the_same_content(job: Path) -> None:
    md = (job / "report.md").read_text()
    doc = _doc(job / "report.html")
    for h in doc.findall(".//h2") + doc.findall(".//h3"):
        title = h.text_content()
        if title != "Contents":
            assert title in md, title
    for target in re.findall(r"!\[[^\]]*\]\(([^)]+)\)", md):
        assert (job / target).is_file(), target


def test_deterministic_but_for_the_timestamp(job: Path, monkeypatch: pytest.MonkeyPatch,
                                             tmp_path: Path) -> None:
    from sensorgap.report import write_report

    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")
    write_report(job)
    a = (job / "report.html").read_bytes()
    write_report(job)
    assert (job / "report.html").read_bytes() == a
    monkeypatch.delenv("SOURCE_DATE_EPOCH")
    write_report(job)
    b = (job / "report.html").read_text()
    diff = [(x, y) for x, y in zip(a.decode().splitlines(), b.splitlines(), strict=True)
            if x != y]
    assert len(diff) == 1 and "Generated (UTC)" in diff[0][1]


def test_degrades_when_parts_were_not_run(tmp_path: Path) -> None:
    run_search("system_b", ["crossing_pedestrian"], ["clear"], 60, 1, 2, tmp_path,
               strategy="lhs", progress=False)
    assert main(["report", "--run", str(tmp_path)]) == 0
    doc = _doc(tmp_path / "report.html")
    for sid in ("nearfield", "coverage", "table-iv"):
        assert "Not part of this run." in doc.get_element_by_id(sid).text_content()
    assert "Not exported" in doc.get_element_by_id("scenarios").text_content()


def test_bad_files_are_one_line_exit_2(job: Path, tmp_path: Path,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad"
    shutil.copytree(job, bad)
    (bad / "nearfield" / "nearfield.json").write_text("{not json")
    assert main(["report", "--run", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert "nearfield.json" in err and len(err.splitlines()) == 1
    assert main(["report", "--run", str(tmp_path / "nope")]) == 2


def test_compare_a_vs_b(job: Path, tmp_path: Path) -> None:
    b = tmp_path / "system_b"
    run_search("system_b", ["crossing_pedestrian", "stopped_rural_curve"],
               ["clear", "fog_50"], 300, 1, 4, b, strategy="lhs", progress=False)
    from sensorgap.analysis.nearfield import write_nearfield
    from sensorgap.models import load_system

    write_nearfield(load_system("system_b"), b / "nearfield")
    out = tmp_path / "cmp"
    assert main(["report", "--compare", str(job), str(b), "--out", str(out)]) == 0
    doc = _doc(out / "report.html")
    near = doc.get_element_by_id("nearfield").text_content()
    assert "System A" in near and "System B" in near
    scen = doc.get_element_by_id("scenarios")
    assert scen.findall(".//table") and (out / "comparison.csv").is_file()
    assert (out / "report.md").is_file() and (out / "manifest.json").is_file()


CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


@pytest.mark.skipif(CHROMIUM is None, reason="headless Chromium is not installed "
                    "(Debian package chromium)")
def test_renders_in_headless_chromium_without_console_errors(job: Path,
                                                              tmp_path: Path) -> None:
    assert CHROMIUM is not None
    proc = subprocess.run(
        [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
         "--no-first-run", "--disable-background-networking", "--disable-component-update",
         "--disable-sync", f"--user-data-dir={tmp_path / 'profile'}", "--enable-logging=stderr",
         "--v=0", "--dump-dom", (job / "report.html").as_uri()],
        capture_output=True, timeout=120, check=False)
    assert proc.returncode == 0, proc.stderr.decode()[-500:]
    dom = proc.stdout.decode()
    assert "sensorgap audit report" in dom and dom.count("<img") >= 10
    console = [ln for ln in proc.stderr.decode().splitlines() if "CONSOLE" in ln]
    assert console == [], console
