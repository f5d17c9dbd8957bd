"""A small document model rendered twice: one self-contained HTML file (figures embedded as
data URIs, no network resources, no scripts, a print stylesheet) and Markdown with linked
PNGs, so both carry the same content (``report.html`` for assessors, ``report.md`` for
review diffs).

Figures are embedded in the HTML as 256-colour PNGs (fast octree, no dithering; the maps use
256-entry colour maps), about a third of the bytes of matplotlib's RGBA files; the Markdown
links the full files. Layout (tested in headless Chromium): tables wrap their text and sit
in a box that scrolls sideways only if they cannot fit, so the page never overflows a
1280 px window; in print every top-level section starts a new page except short ones (no
table, figure or subsection: e.g. "Not part of this run."), which follow on the same page.
"""

from __future__ import annotations

import base64
import html
import io
import re
import struct
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

from sensorgap.errors import InputError, escape_controls
from sensorgap.filesio import regular_file_size
from sensorgap.markdown import md_cell, md_text

#: What a section says when its part of the pipeline was not run (one line).
NOT_RUN = "Not part of this run."


@dataclass
class Para:
    """A paragraph of plain text."""

    text: str


@dataclass
class Link:
    """A link to a file of the run folder (a table cell or list item)."""

    text: str
    href: str


#: A table cell: text or a link.
Cell = str | Link


@dataclass
class Table:
    """A table of text (or link) cells."""

    headers: list[str]
    rows: Sequence[Sequence[Cell]]
    caption: str = ""


@dataclass
class Image:
    """A PNG figure (``path``) with a caption; ``rel`` is its path relative to the report."""

    path: Path
    caption: str
    rel: str = ""


@dataclass
class Links:
    """Links to files of the run folder: (text, relative href)."""

    items: list[tuple[str, str]]


@dataclass
class Bullets:
    """A list of sentences (numbered when ``ordered``); an item may be (lead, text): the
    lead in bold."""

    items: Sequence[str | tuple[str, str]]
    ordered: bool = False


Block = Para | Table | Image | Links | Bullets


@dataclass
class Section:
    """A titled section (``id`` is its HTML anchor)."""

    id: str
    title: str
    blocks: list[Block] = field(default_factory=list)
    subsections: list[Section] = field(default_factory=list)

    @property
    def short(self) -> bool:
        """No table, figure or subsection: printed without a page of its own."""
        return not self.subsections and not any(isinstance(b, Table | Image) for b in self.blocks)


_CSS = """
body{font-family:system-ui,-apple-system,'Segoe UI',sans-serif;margin:0.5em auto 2em;
max-width:1100px;line-height:1.4;color:#111;padding:0 1em}
h1{border-bottom:2px solid #333;font-size:1.6em;margin:0.3em 0}
h2{border-bottom:1px solid #999;margin-top:2em}
.meta{color:#555;font-size:0.85em;margin:0.2em 0}
#summary h2{margin-top:0.6em}#summary h3{margin:0.7em 0 0.2em}
#summary p,#summary li{margin:0.25em 0}#summary ol,#summary ul{margin:0.2em 0;padding-left:1.6em}
div.tw{overflow-x:auto;max-width:100%}
table{border-collapse:collapse;margin:0.8em 0;font-size:0.85em}
th,td{border:1px solid #bbb;padding:2px 6px;text-align:left;vertical-align:top;
overflow-wrap:break-word}
th{background:#eee}caption{caption-side:top;text-align:left;font-style:italic}
p,li{overflow-wrap:anywhere}figure{margin:1em 0}img{max-width:100%;height:auto}
figcaption{font-size:0.85em;color:#444}nav li{margin:0.1em 0}
@page{size:A4;margin:10mm}
@media print{body{max-width:none;margin:0;padding:0;font-size:10pt}h1{font-size:14pt}
#summary{font-size:8.5pt;break-before:auto}section.top{break-before:page}
section.short{break-before:auto}
nav{break-before:page}div.tw{overflow:visible}figure,tr{break-inside:avoid}
h2,h3{break-after:avoid}a{color:#000}}
"""


@lru_cache(maxsize=64)
def compact_png(data: bytes) -> bytes:
    """A PNG as at most 256 colours on white (fast octree, no dithering), or the original
    when that is not smaller. Deterministic (cached per process: a report written again
    reuses the figures it already reduced). Octree rather than median cut (session 18,
    the default job's 21 figures): 0.55 s instead of 2.1 s, 0.82 MB instead of 0.95 MB,
    and the figures' colours kept (median cut merged the legend's pink and cyan into grey
    and banded the colour bar)."""
    from PIL import Image as PILImage

    with PILImage.open(io.BytesIO(data)) as im:
        rgb = im.convert("RGB")
        if im.mode in ("RGBA", "LA", "P"):
            rgba = im.convert("RGBA")
            rgb = PILImage.new("RGB", im.size, "white")
            rgb.paste(rgba, mask=rgba.getchannel("A"))
        q = rgb.quantize(
            colors=256, method=PILImage.Quantize.FASTOCTREE, dither=PILImage.Dither.NONE
        )
        buf = io.BytesIO()
        q.save(buf, "PNG")
    out = buf.getvalue()
    return out if len(out) < len(data) else data


#: A figure a report embeds or links (a PNG of a run folder): at most this many bytes and
#: pixels. sensorgap's largest is a comparison figure of at most 1,440 x 2,532 pixels
#: (3.6 Mpx), its largest files about 0.33 MB; a PNG of 10,000 x 10,000 1-bit pixels is
#: 12 kB but took 1.6 GB to embed, figures padded to 1.5 GB after their end 5 GB
#: (hostile round 25). ``compact_png`` keeps at most 64 figures: <= 0.7 GB at the limits.
MAX_FIGURE_BYTES = 5_000_000
MAX_FIGURE_PIXELS = 25_000_000
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def embedded_png(path: Path) -> bytes:
    """The PNG figure ``path`` as a report embeds it (``compact_png``), after checking that
    it is a PNG of at most ``MAX_FIGURE_BYTES`` and ``MAX_FIGURE_PIXELS`` that decodes
    without a warning; anything else -> ``InputError`` naming the file."""
    try:
        regular_file_size(path, MAX_FIGURE_BYTES, "figure", " (a PNG)")
        with path.open("rb") as f:
            head = f.read(24)
    except OSError as exc:
        raise InputError(path, "", f"unreadable figure: {exc.strerror or exc}") from None
    if len(head) < 24 or head[:8] != _PNG_SIGNATURE or head[12:16] != b"IHDR":
        raise InputError(path, "", "not a PNG image; draw it again with the command that made it")
    w, h = struct.unpack(">II", head[16:24])
    if not (w >= 1 and h >= 1 and w * h <= MAX_FIGURE_PIXELS):
        raise InputError(
            path, "", f"a PNG of {w} x {h} pixels; at most {MAX_FIGURE_PIXELS} pixels allowed"
        )
    from PIL import Image as PILImage

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            return compact_png(path.read_bytes())
    except (
        OSError,
        ValueError,
        SyntaxError,
        EOFError,
        Warning,
        PILImage.DecompressionBombError,
    ) as exc:
        raise InputError(path, "", f"unreadable PNG image: {str(exc)[:120]}") from None


_UNIT = re.compile(r"(\d) (?=(?:s|m|m²|km|km/h|mm/h|m/s2|dB|deg|°)(?![\w/²]))")


def _h(text: str) -> str:
    """Text for HTML: escaped, control and format characters written as escapes
    (``errors.escape_controls``: none reaches the page raw)."""
    return html.escape(escape_controls(text))


def _prose(text: str) -> str:
    """Escaped text with a number and its unit kept on one line (no-break space)."""
    return _h(_UNIT.sub("\\1\u00a0", text))


def _breakable(text: str) -> str:
    """Escaped text with optional line breaks after ``_`` and before ``@`` (long names such
    as ``pedestrian_behind_parked_cars`` or ``clear@sun302/24`` may wrap in a narrow
    column; copied text is unchanged)."""
    return _h(text).replace("_", "_<wbr>").replace("@", "<wbr>@")


def _html_cell(c: Cell) -> str:
    if isinstance(c, Link):
        return f'<a href="{_h(c.href)}">{_breakable(c.text)}</a>'
    return _breakable(c)


def _html_block(b: Block) -> str:
    if isinstance(b, Para):
        return f"<p>{_prose(b.text)}</p>"
    if isinstance(b, Bullets):
        tag = "ol" if b.ordered else "ul"
        items = "".join(
            f"<li>{_prose(t)}</li>"
            if isinstance(t, str)
            else f"<li><b>{_prose(t[0])}</b> {_prose(t[1])}</li>"
            for t in b.items
        )
        return f"<{tag}>{items}</{tag}>"
    if isinstance(b, Table):
        cap = f"<caption>{_h(b.caption)}</caption>" if b.caption else ""
        head = "".join(f"<th>{_breakable(h)}</th>" for h in b.headers)
        body = "".join(
            "<tr>" + "".join(f"<td>{_html_cell(c)}</td>" for c in r) + "</tr>" for r in b.rows
        )
        return (
            f'<div class="tw"><table>{cap}<thead><tr>{head}</tr></thead>'
            f"<tbody>{body}</tbody></table></div>"
        )
    if isinstance(b, Image):
        data = base64.b64encode(embedded_png(b.path)).decode("ascii")
        cap = _h(b.caption)
        return (
            f'<figure><img src="data:image/png;base64,{data}" alt="{cap}">'
            f"<figcaption>{cap}</figcaption></figure>"
        )
    items = "".join(f'<li><a href="{_h(href)}">{_h(text)}</a></li>' for text, href in b.items)
    return f'<ul class="links">{items}</ul>'


def _html_section(s: Section, level: int) -> str:
    cls = ""
    if level == 2:
        cls = ' class="top short"' if s.short else ' class="top"'
    parts = [
        f'<section id="{_h(s.id)}"{cls}>',
        f"<h{level}>{_h(s.title)}</h{level}>",
    ]
    parts += [_html_block(b) for b in s.blocks]
    parts += [_html_section(sub, min(level + 1, 6)) for sub in s.subsections]
    parts.append("</section>")
    return "\n".join(parts)


def render_html(
    title: str, meta: list[str], sections: list[Section], front: Section | None = None
) -> str:
    """One self-contained HTML page (no scripts, no external resources); ``front`` (the
    summary) comes right after the title, before the table of contents."""
    toc = "".join(f'<li><a href="#{_h(s.id)}">{_h(s.title)}</a></li>' for s in sections)
    metas = "".join(f'<p class="meta">{_h(m)}</p>' for m in meta)
    head = "" if front is None else _html_section(front, 2)
    body = "\n".join(_html_section(s, 2) for s in sections)
    return (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        '<meta name="viewport" content="width=device-width, initial-scale=1">'
        f"<title>{_h(title)}</title><style>{_CSS}</style></head><body>"
        f"<h1>{_h(title)}</h1>{metas}{head}"
        f"<nav><h2>Contents</h2><ol>{toc}</ol></nav>{body}</body></html>\n"
    )


def _md(text: str) -> str:
    """Text for Markdown (``markdown.md_text``) in a paragraph, a list item, a caption or a
    heading: one line, its line breaks as spaces (a line of a text given by the user,
    starting with ``#`` or ``|``, became a heading or a table row; hostile round 42)."""
    return md_text(text).replace("\n", " ")


def _md_cell(c: Cell) -> str:
    if isinstance(c, Link):
        return f"[{_md_cell(c.text)}]({c.href})"
    return md_cell(c)


def _md_block(b: Block) -> str:
    if isinstance(b, Para):
        return _md(b.text)
    if isinstance(b, Bullets):
        return "\n".join(
            f"{f'{i}.' if b.ordered else '-'} "
            + (_md(t) if isinstance(t, str) else f"**{_md(t[0])}** {_md(t[1])}")
            for i, t in enumerate(b.items, start=1)
        )
    if isinstance(b, Table):
        lines = [f"*{_md(b.caption)}*", ""] if b.caption else []
        lines.append("| " + " | ".join(_md_cell(h) for h in b.headers) + " |")
        lines.append("|" + "---|" * len(b.headers))
        lines += ["| " + " | ".join(_md_cell(c) for c in r) + " |" for r in b.rows]
        return "\n".join(lines)
    if isinstance(b, Image):
        return f"![{_md(b.caption)}]({b.rel or b.path.name})\n\n*{_md(b.caption)}*"
    return "\n".join(f"- [{_md(text)}]({href})" for text, href in b.items)


def _md_section(s: Section, level: int) -> str:
    parts = [f"{'#' * level} {_md(s.title)}"]
    parts += [_md_block(b) for b in s.blocks]
    parts += [_md_section(sub, min(level + 1, 6)) for sub in s.subsections]
    return "\n\n".join(parts)


def render_markdown(
    title: str, meta: list[str], sections: list[Section], front: Section | None = None
) -> str:
    """The same content as Markdown with linked PNGs (``front`` first)."""
    head = [f"# {_md(title)}", *(_md(m) for m in meta)]
    secs = ([front] if front is not None else []) + sections
    return "\n\n".join([*head, *(_md_section(s, 2) for s in secs)]) + "\n"
