"""``sensorgap.markdown``: a name in a Markdown table cell is shown as written (hostile
round seventeen: a vehicle named ``B|pipe <b>bold</b> &amp;`` split comparison.md's header
into 19 cells over 15 and rendered as HTML)."""

from __future__ import annotations

from sensorgap.markdown import md_cell, md_text


def test_a_table_cell_keeps_its_pipes_tags_and_entities_as_text() -> None:
    name = "B|pipe <b>bold</b> &amp;\nnext"
    cell = md_cell(name)
    assert cell == "B\\|pipe &lt;b>bold&lt;/b> &amp;amp; next"
    # a row of three such cells has exactly three cells for a renderer
    row = "| " + " | ".join([cell] * 3) + " |"
    assert row.replace("\\|", "").count("|") == 4
    assert md_text("a < b & c") == "a < b & c"  # not HTML-like: left alone
