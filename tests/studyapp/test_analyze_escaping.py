"""Source names and prompts come from users: ``analyze`` writes them as text, never markup.

Every Markdown table ``analyze`` writes is rendered by a CommonMark renderer with GFM
tables (markdown-it-py, raw HTML on as CommonMark has it): no tag, link or image of
the input gets through, every row keeps its cells, and the names read back as typed.
"""

import html
import re

import pytest
from django.core.management import call_command
from markdown_it import MarkdownIt

from analysis.report import markdown_table, markdown_text
from analysis.simulate import simulate
from analysis.tables import write_responses

HOSTILE_SOURCES = [
    "<script>alert('source')</script>",
    "[click](https://evil.example/x) | extra cell",
    "![pixel](https://evil.example/p.png) **bold** `code` _em_ \\| two\nlines",
]
HOSTILE_PROMPTS = ["<img src=x onerror=alert(1)> a person waves", "a person <b>walks</b> & runs"]
RENDER = MarkdownIt("commonmark").enable("table").enable("strikethrough")


def cells(line: str) -> int:
    """Return the cells of a Markdown table row (pipes not escaped by a backslash)."""
    return len(re.findall(r"(?<!\\)(?:\\\\)*\|", line)) - 1


@pytest.fixture
def report(tmp_path):
    table = simulate("ranking", participants=12, trials=4, seed=1)
    names = dict(zip(["real", "a2m", "cond_gru"], HOSTILE_SOURCES))
    table["source"] = table["source"].map(lambda s: names.get(s, s))
    actions = sorted(table["action"].unique())
    table["prompt"] = table["action"].map(lambda a: HOSTILE_PROMPTS[actions.index(a) % 2])
    out = tmp_path / "report"
    call_command("analyze", responses=str(write_responses(table, tmp_path / "r.csv")),
                 out=str(out), bootstrap=20)
    return out


def test_analyze_writes_user_names_as_text_in_every_markdown_table(report):
    tables = sorted(report.rglob("*.md"))
    assert tables
    seen = ""
    for path in tables:
        text = path.read_text()
        rows = [line for line in text.splitlines() if line.startswith("|")]
        assert len({cells(line) for line in rows}) == 1, path.name  # no cell added or lost
        rendered = RENDER.render(text)
        for tag in ("<script", "<img", "<a ", "<b>"):  # (emphasis and code: read back below)
            assert tag not in rendered, (path.name, tag)
        seen += html.unescape(re.sub(r"<[^>]+>", "", rendered))
    for name in [*HOSTILE_SOURCES, *HOSTILE_PROMPTS]:
        assert " ".join(name.splitlines()) in seen, name  # read back as typed
    page = (report / "report.html").read_text()
    assert "<script" not in page and "<img src=x" not in page


def test_markdown_text_escapes_markup_but_keeps_names_readable():
    assert markdown_text("n_judgements") == "n_judgements"
    assert markdown_text("_em_") == "\\_em\\_"
    assert markdown_text("<b>&</b>") == "&lt;b&gt;&amp;&lt;/b&gt;"
    assert markdown_text("a\\|b") == "a\\\\\\|b"  # the backslash cannot unescape the pipe
    import pandas as pd

    table = markdown_table(pd.DataFrame({"<th>": ["x"]}), title="<h1>Title</h1>")
    assert "<" not in table and table.startswith("**&lt;h1&gt;Title&lt;/h1&gt;**")
