"""The report document: Markdown tables escaped, HTML self-contained and escaped."""

from __future__ import annotations

from wovenskin.study.document import Bullets, Heading, Image, Table, Text, to_html, to_markdown


def test_markdown_and_html_render_the_same_blocks(tmp_path):
    (tmp_path / "a.png").write_bytes(b"\x89PNG fake")
    blocks = [
        Heading("Report <1>", 1),
        Text("**SYNTHETIC** a < b"),
        Bullets(("one", "two")),
        Table(("x", "y|z"), (("1", "a|b"),)),
        Image("a.png", "a plot"),
    ]
    md = to_markdown(blocks)
    assert md.startswith("# Report <1>\n\n**SYNTHETIC** a < b\n\n- one\n- two\n")
    assert "| x | y\\|z |\n|---|---|\n| 1 | a\\|b |" in md
    assert "![a plot](a.png)" in md
    page = to_html(blocks, "T", tmp_path)
    assert "<h1>Report &lt;1&gt;</h1>" in page
    assert "<p><strong>SYNTHETIC</strong> a &lt; b</p>" in page
    assert "<th>y|z</th>" in page and "<td>a|b</td>" in page
    assert 'src="data:image/png;base64,iVBORyBmYWtl"' in page
