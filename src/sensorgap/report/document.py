"""A small document model rendered twice: one self-contained HTML file (figures embedded as
data URIs, no network resources, a print stylesheet) and Markdown with linked PNGs, so both
carry the same content (``report.html`` for assessors, ``report.md`` for review diffs)."""

from __future__ import annotations

import base64
import html
from dataclasses import dataclass, field
from pathlib import Path


@dataclass
class Para:
    """A paragraph of plain text."""

    text: str


@dataclass
class Table:
    """A table of strings."""

    headers: list[str]
    rows: list[list[str]]
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


Block = Para | Table | Image | Links


@dataclass
class Section:
    """A titled section (``id`` is its HTML anchor)."""

    id: str
    title: str
    blocks: list[Block] = field(default_factory=list)
    subsections: list[Section] = field(default_factory=list)


_CSS = """
body{font-family:system-ui,-apple-system,'Segoe UI',sans-serif;margin:2em auto;max-width:1100px;
line-height:1.4;color:#111;padding:0 1em}
h1{border-bottom:2px solid #333}h2{border-bottom:1px solid #999;margin-top:2em}
table{border-collapse:collapse;margin:0.8em 0;font-size:0.85em}
th,td{border:1px solid #bbb;padding:2px 6px;text-align:left;vertical-align:top}
th{background:#eee}caption{caption-side:top;text-align:left;font-style:italic}
figure{margin:1em 0}img{max-width:100%;height:auto}figcaption{font-size:0.85em;color:#444}
nav li{margin:0.1em 0}.meta{color:#555;font-size:0.9em}
@media print{body{max-width:none;margin:0}section.top{page-break-before:always}
nav{page-break-after:always}a{color:#000}}
"""


def _html_block(b: Block) -> str:
    if isinstance(b, Para):
        return f"<p>{html.escape(b.text)}</p>"
    if isinstance(b, Table):
        cap = f"<caption>{html.escape(b.caption)}</caption>" if b.caption else ""
        head = "".join(f"<th>{html.escape(h)}</th>" for h in b.headers)
        body = "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in r) + "</tr>"
                       for r in b.rows)
        return f"<table>{cap}<thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"
    if isinstance(b, Image):
        data = base64.b64encode(b.path.read_bytes()).decode("ascii")
        cap = html.escape(b.caption)
        return (f'<figure><img src="data:image/png;base64,{data}" alt="{cap}">'
                f"<figcaption>{cap}</figcaption></figure>")
    items = "".join(f'<li><a href="{html.escape(href)}">{html.escape(text)}</a></li>'
                    for text, href in b.items)
    return f"<ul class=\"links\">{items}</ul>"


def _html_section(s: Section, level: int) -> str:
    cls = ' class="top"' if level == 2 else ""
    parts = [f'<section id="{html.escape(s.id)}"{cls}>',
             f"<h{level}>{html.escape(s.title)}</h{level}>"]
    parts += [_html_block(b) for b in s.blocks]
    parts += [_html_section(sub, min(level + 1, 6)) for sub in s.subsections]
    parts.append("</section>")
    return "\n".join(parts)


def render_html(title: str, meta: list[str], sections: list[Section]) -> str:
    """One self-contained HTML page (no scripts, no external resources)."""
    toc = "".join(f'<li><a href="#{html.escape(s.id)}">{html.escape(s.title)}</a></li>'
                  for s in sections)
    metas = "".join(f'<p class="meta">{html.escape(m)}</p>' for m in meta)
    body = "\n".join(_html_section(s, 2) for s in sections)
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>{html.escape(title)}</title><style>{_CSS}</style></head><body>"
            f"<h1>{html.escape(title)}</h1>{metas}<nav><h2>Contents</h2><ol>{toc}</ol></nav>"
            f"{body}</body></html>\n")


def _md_cell(c: str) -> str:
    return c.replace("|", "\\|").replace("\n", " ")


def _md_block(b: Block) -> str:
    if isinstance(b, Para):
        return b.text
    if isinstance(b, Table):
        lines = [f"*{b.caption}*", ""] if b.caption else []
        lines.append("| " + " | ".join(_md_cell(h) for h in b.headers) + " |")
        lines.append("|" + "---|" * len(b.headers))
        lines += ["| " + " | ".join(_md_cell(c) for c in r) + " |" for r in b.rows]
        return "\n".join(lines)
    if isinstance(b, Image):
        return f"![{b.caption}]({b.rel or b.path.name})\n\n*{b.caption}*"
    return "\n".join(f"- [{text}]({href})" for text, href in b.items)


def _md_section(s: Section, level: int) -> str:
    parts = [f"{'#' * level} {s.title}"]
    parts += [_md_block(b) for b in s.blocks]
    parts += [_md_section(sub, min(level + 1, 6)) for sub in s.subsections]
    return "\n\n".join(parts)


def render_markdown(title: str, meta: list[str], sections: list[Section]) -> str:
    """The same content as Markdown with linked PNGs."""
    head = [f"# {title}", *meta]
    return "\n\n".join([*head, *(_md_section(s, 2) for s in sections)]) + "\n"
