"""Text made safe for Markdown (``report.md``, ``comparison.md``): what a renderer would
take for HTML or for table syntax is escaped, so a name is shown as written."""

from __future__ import annotations

import re

from sensorgap.errors import escape_controls

#: What a Markdown renderer would take for HTML in text: a tag's or comment's opening
#: ``<`` and an entity's ``&`` (a family file named ``st op&<x>.toml`` printed raw; the
#: report's own ``difference/<map>/`` vanished as a tag).
_MD_HTML = re.compile(r"<(?=[A-Za-z/!?])|&(?=#?[A-Za-z0-9]+;)")


def md_text(text: str) -> str:
    """Text for Markdown: HTML-like ``<`` and ``&`` as entities (shown as themselves),
    control and format characters escaped (``errors.escape_controls``)."""
    return _MD_HTML.sub(lambda m: "&lt;" if m.group(0) == "<" else "&amp;", escape_controls(text))


def md_cell(text: str) -> str:
    """Text for a Markdown table cell: ``md_text`` with ``|`` escaped (it would end the
    cell) and line breaks as spaces (they would end the row)."""
    return md_text(text).replace("|", "\\|").replace("\n", " ")
