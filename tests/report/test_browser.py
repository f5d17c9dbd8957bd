"""What a person sees: the reports rendered by headless Chromium (Debian package
``chromium``) over the DevTools protocol (tests/report/chromium.py). Screenshots and PDFs
are written to each test's temporary folder for inspection."""

from __future__ import annotations

import re
import struct
from pathlib import Path
from typing import Any

import pytest

from sensorgap.report.summary import MAX_WEAKNESSES
from tests.report.chromium import CHROMIUM, Browser

pytestmark = pytest.mark.skipif(
    CHROMIUM is None, reason="headless Chromium is not installed (Debian package chromium)"
)

#: The window an assessor opens the report in (CSS px).
WIDTH, HEIGHT = 1280, 800
#: An A4 page less the report's 10 mm print margins (@page), CSS px at 96 per inch.
A4_W, A4_H = round(190 / 25.4 * 96), int(277 / 25.4 * 96)

_BOX = """(sel) => { const e = document.querySelector(sel); if (!e) return null;
  const r = e.getBoundingClientRect();
  return {top: r.top + scrollY, bottom: r.bottom + scrollY, left: r.left, right: r.right,
          width: r.width, height: r.height}; }"""
_LAYOUT = f"""(() => {{ const box = {_BOX};
  const cut = [...document.querySelectorAll('div.tw')]
    .filter(d => d.scrollWidth > d.clientWidth + 1)
    .map(d => [d.closest('section').id, d.scrollWidth, d.clientWidth]);
  const wide = [...document.querySelectorAll('body *')]
    .filter(e => e.getBoundingClientRect().right > innerWidth + 0.5)
    .map(e => e.tagName + ' in #' + (e.closest('section') || {{id: ''}}).id).slice(0, 5);
  return {{innerWidth, innerHeight, scrollWidth: document.documentElement.scrollWidth,
          summary: box('#summary'), heading: box('#summary h2'),
          weakness: box('#weaknesses li'), cut, wide,
          rowHeights: [...document.querySelectorAll('tbody tr')]
            .map(t => t.getBoundingClientRect().height),
          images: [...document.images].map(i => [i.complete, i.naturalWidth])}}; }})()"""


def _png_size(path: Path) -> tuple[int, int]:
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    w, h = struct.unpack(">II", data[16:24])
    return w, h


def _errors(b: Browser) -> list[Any]:
    """Console errors, uncaught exceptions and failed loads the page reported."""
    out = []
    for ev in b.events:
        m, p = ev.get("method"), ev.get("params", {})
        if m == "Runtime.exceptionThrown" or (
            m == "Runtime.consoleAPICalled" and p.get("type") in ("error", "assert")
        ):
            out.append(p)
        elif m == "Log.entryAdded" and p.get("entry", {}).get("level") == "error":
            out.append(p["entry"])
    return out


def test_summary_above_the_fold_without_overflow(job: Path, tmp_path: Path) -> None:
    with Browser() as b:
        b.call("Log.enable")
        b.open(job / "report.html", WIDTH, HEIGHT)
        m = b.eval(_LAYOUT)
        fold = b.screenshot(tmp_path / "report_1280x800.png")
        s = m["summary"]
        whole = b.screenshot(
            tmp_path / "summary.png", {"x": 0, "y": s["top"], "width": WIDTH, "height": s["height"]}
        )
        errors = _errors(b)
    assert (m["innerWidth"], m["innerHeight"]) == (WIDTH, HEIGHT)
    assert _png_size(fold) == (WIDTH, HEIGHT) and _png_size(whole)[0] == WIDTH
    # the summary heading and the whole first weakness are in the first window
    assert 0 <= m["heading"]["top"] < m["heading"]["bottom"] <= 200
    assert m["heading"]["bottom"] < m["weakness"]["top"]
    assert m["weakness"]["bottom"] <= HEIGHT, m["weakness"]
    # no horizontal overflow: the page and every table fit the window
    assert m["scrollWidth"] <= WIDTH and m["wide"] == [], m["wide"]
    assert m["cut"] == [], m["cut"]
    # every image of the page loaded (maps, near field, far field, one per ranked scenario)
    n_img = (job / "report.html").read_text(encoding="utf-8").count("<img")
    assert all(ok and w > 0 for ok, w in m["images"]) and len(m["images"]) == n_img >= 15
    assert errors == [], errors


def test_compare_report_readable_at_1280(compared: Path, tmp_path: Path) -> None:
    with Browser() as b:
        b.call("Log.enable")
        b.open(compared / "report.html", WIDTH, HEIGHT)
        m = b.eval(_LAYOUT)
        box = b.eval(f"({_BOX})('#scenarios')")
        b.screenshot(
            tmp_path / "compare_scenarios.png",
            {"x": 0, "y": box["top"], "width": WIDTH, "height": min(box["height"], 3000)},
        )
        errors = _errors(b)
    # every column of every table visible without scrolling; no ~450 px rows
    assert m["scrollWidth"] <= WIDTH and m["cut"] == [], m["cut"]
    assert m["rowHeights"] and max(m["rowHeights"]) <= 120, max(m["rowHeights"])
    assert errors == [], errors


def test_printed_pages(job: Path, search_only: Path, tmp_path: Path) -> None:
    """Printed (A4): the summary fits the first page; a section with a table or figure
    starts a page, a short one ("Not part of this run.") follows on the page before."""
    breaks_js = """[...document.querySelectorAll('body > section')].map(s =>
        [s.id, s.classList.contains('short'), getComputedStyle(s).breakBefore])"""
    pages = {}
    for name, folder in (("job", job), ("search_only", search_only)):
        with Browser() as b:
            b.open(folder / "report.html", A4_W, A4_H)
            b.call("Emulation.setEmulatedMedia", {"media": "print"})
            summary = b.eval(f"({_BOX})('#summary')")
            items = b.eval(
                "[...document.querySelectorAll('#weaknesses li')]"
                ".map(l => l.getBoundingClientRect().height)"
            )
            rows = b.eval(
                "[...document.querySelectorAll('#test-first tbody tr')]"
                ".map(r => r.getBoundingClientRect().height)"
            )
            nav = b.eval("getComputedStyle(document.querySelector('nav')).breakBefore")
            breaks = b.eval(breaks_js)
            pdf = b.pdf()
        (tmp_path / f"{name}.pdf").write_bytes(pdf)
        pages[name] = len(re.findall(rb"/Type\s*/Page\b", pdf))
        assert summary["bottom"] <= A4_H, (name, summary)
        if items:  # room for the longest weakness up to the maximum number of them
            more = (MAX_WEAKNESSES - len(items)) * (1.1 * max(items) + max(rows))
            assert summary["bottom"] + more <= A4_H, (name, summary, items, rows)
        assert nav == "page"
        assert breaks[0] == ["summary", False, "auto"]
        for sid, short, brk in breaks[1:]:
            assert brk == ("auto" if short else "page"), (name, sid)
    # the report of a search without near field, coverage and far field prints on fewer
    # pages than the full one: its "Not part of this run." sections take none of their own
    assert 0 < pages["search_only"] < pages["job"]
