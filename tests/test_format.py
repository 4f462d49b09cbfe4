"""markdown_cell: a user's name as Markdown table cell text that renders as the name itself (review A)."""

from __future__ import annotations

import html
import re

import pytest

from torchmeshmetric._format import markdown_cell
from torchmeshmetric.viz.html_report import markdown_html

# (name, its cell text). A name rendered bold/italic/struck, as code, a link, an image, HTML, math or an entity.
ESCAPED = [
    ("**a**", r"\*\*a\*\*"),
    ("_a_", r"\_a\_"),
    ("a*b*c", r"a\*b\*c"),
    ("__init__", r"\_\_init\_\_"),
    ("~~s~~", r"\~\~s\~\~"),
    ("`c`", r"\`c\`"),
    ("[x](http://y)", r"\[x\](http://y)"),
    ("![i](j)", r"!\[i\](j)"),
    ("<b>hi</b>", r"\<b\>hi\</b\>"),
    ("budget $5 to $10", r"budget \$5 to \$10"),
    ("a&amp;b", r"a\&amp;b"),
    ("a|b\\", r"a\|b\\"),
]
# Names whose characters change nothing: written as they are (a "_" between letters or digits opens no emphasis).
UNCHANGED = ["Orig QEM", "orig_qem", "longdress_vox10_1051", "é_ü", "QEM 50 %", "A&B", "cat1-A", "C:x"]


@pytest.mark.parametrize(("name", "cell"), ESCAPED)
def test_markdown_specials_are_escaped_and_render_as_the_name(name: str, cell: str) -> None:
    # Only "\" and "|" were escaped: "**a**" showed in bold, "_a_" in italics, "<b>" as HTML.
    assert markdown_cell(name) == cell
    page = markdown_html(f"| name |\n|---|\n| {markdown_cell(name)} |\n")
    td = re.search(r"<td>(.*)</td>", page)
    assert td is not None and html.unescape(td.group(1)) == name and "<" not in td.group(1)


@pytest.mark.parametrize("name", UNCHANGED)
def test_names_without_markdown_specials_are_unchanged(name: str) -> None:
    assert markdown_cell(name) == name
