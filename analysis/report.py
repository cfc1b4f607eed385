"""Write a study result to a folder: HTML report, tables, figures and ``summary.json``.

    out/report.html        self-contained: figures embedded as PNG, every table, methods
    out/summary.json       per source: score, interval, N; the order of sources
    out/<table>.csv|.md|.tex
    out/<figure>.png|.svg
"""

from __future__ import annotations

import base64
import html
import io
import json
import re
from pathlib import Path

import matplotlib
import pandas as pd

from analysis.figures import STYLE, save_figure
from analysis.formatting import display_frame, interval, number
from analysis.tables import neutralise_formulas

LATEX_SPECIALS = {
    "\\": r"\textbackslash{}", "&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#", "_": r"\_",
    "{": r"\{", "}": r"\}", "~": r"\textasciitilde{}", "^": r"\textasciicircum{}",
}


def write_report(result, out, title: str | None = None) -> list[Path]:
    """Write every output of ``result`` (a ``StudyResult``) under ``out``; return the paths."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    summary = out / "summary.json"
    summary.write_text(json.dumps(result.summary(), indent=2, allow_nan=False) + "\n")
    written.append(summary)
    for table in result.tables:
        written += write_table(table.frame, out / table.name, table.title)
    figures = []
    for plot in result.analysis.plots:
        fig = plot.draw()
        written += save_figure(fig, out / f"{plot.name}.png", svg=True)
        figures.append((plot, png_base64(fig)))
    page = out / "report.html"
    page.write_text(render_html(result, figures, title))
    written.append(page)
    return written


def write_table(frame: pd.DataFrame, stem: Path, title: str = "") -> list[Path]:
    """Write ``frame`` as ``stem``.csv (full precision), .md and .tex (rounded)."""
    stem = Path(stem)
    csv, md, tex = (stem.with_suffix(suffix) for suffix in (".csv", ".md", ".tex"))
    named_index = any(name is not None for name in frame.index.names)
    neutralise_formulas(frame).to_csv(csv, index=named_index)
    shown = display_frame(frame)
    md.write_text(markdown_table(shown, title))
    tex.write_text(latex_table(shown, title, label=f"tab:{stem.name}"))
    return [csv, md, tex]


def markdown_table(shown: pd.DataFrame, title: str = "") -> str:
    """Return a pipe table of ``shown`` (strings), numbers right-aligned; every text is
    written as text (:func:`markdown_text`)."""
    header = [markdown_text(c) for c in shown.columns]
    align = ["---:" if _numeric(shown[c]) else ":---" for c in shown.columns]
    lines = [f"**{markdown_text(title)}**", ""] if title else []
    lines += ["| " + " | ".join(header) + " |", "| " + " | ".join(align) + " |"]
    for row in shown.itertuples(index=False):
        lines.append("| " + " | ".join(markdown_text(v) for v in row) + " |")
    return "\n".join(lines) + "\n"


def markdown_text(value) -> str:
    """Return ``value`` as literal text in Markdown (a table cell, a title).

    Source names, prompts and answers come from users: HTML in them is escaped (``<``,
    ``>``, ``&``), and so is the Markdown that would make a link or image (``[``, ``]``),
    code, emphasis or a new cell (backslash, backtick, ``*``, ``|``, ``~``, and ``_``
    where it could start or end emphasis: ``n_judgements`` stays as it is); line breaks,
    which would end the table's row, become spaces.
    """
    text = html.escape(" ".join(str(value).splitlines()), quote=False)
    text = re.sub(r"([\\`*|~\[\]])", r"\\\1", text)
    return re.sub(r"(?<![A-Za-z0-9])_|_(?![A-Za-z0-9])", r"\\_", text)


def latex_table(shown: pd.DataFrame, title: str = "", label: str = "") -> str:
    """Return a booktabs ``table`` of ``shown`` (strings) with caption and label."""
    spec = "".join("r" if _numeric(shown[c]) else "l" for c in shown.columns)
    lines = [r"\begin{table}[t]", r"\centering"]
    if title:
        lines.append(r"\caption{" + latex_escape(title) + "}")
    if label:
        lines.append(r"\label{" + label + "}")
    lines += [r"\begin{tabular}{" + spec + "}", r"\toprule",
              " & ".join(latex_escape(str(c)) for c in shown.columns) + r" \\", r"\midrule"]
    for row in shown.itertuples(index=False):
        lines.append(" & ".join(latex_escape(str(v)) for v in row) + r" \\")
    lines += [r"\bottomrule", r"\end{tabular}", r"\end{table}"]
    return "\n".join(lines) + "\n"


def latex_escape(text: str) -> str:
    return "".join(LATEX_SPECIALS.get(ch, ch) for ch in text)


def render_html(result, figures, title: str | None = None) -> str:
    """Return the self-contained HTML page of ``result``."""
    esc = html.escape
    heading = title or f"{result.study or 'Study'} ({result.study_type})"
    counts = result.counts
    body = [f"<h1>{esc(heading)}</h1>",
            f"<p class='lead'>{counts['participants']} participants, {counts['judgements']} "
            f"judgements, {counts['trials']} trials. Measure: {esc(result.analysis.measure)}.</p>"]
    body.append("<h2>Result</h2><ol>")
    for source, row in result.analysis.sources.iterrows():
        body.append(f"<li><b>{esc(str(source))}</b>: {number(row['score'])} "
                    f"{interval(row['ci_low'], row['ci_high'])} "
                    f"(n = {int(row['n_judgements'])} judgements, {int(row['n_participants'])} "
                    f"participants)</li>")
    body.append("</ol>")
    body.append(f"<h2>Methods</h2><p class='methods'>{esc(result.methods())}</p>")
    if result.notes:
        body.append("<h2>Notes</h2><ul>" + "".join(f"<li>{esc(n)}</li>" for n in result.notes) + "</ul>")
    body.append("<h2>Figures</h2>")
    for plot, data in figures:
        body.append(f"<figure><img alt='{esc(plot.title)}' src='data:image/png;base64,{data}'>"
                    f"<figcaption>{esc(plot.title)} (<a href='{esc(plot.name)}.svg'>SVG</a>, "
                    f"<a href='{esc(plot.name)}.png'>PNG</a>)</figcaption></figure>")
    body.append("<h2>Tables</h2>")
    for table in result.tables:
        shown = display_frame(table.frame)
        body.append(f"<h3 id='{esc(table.name)}'>{esc(table.title)}</h3>")
        body.append(shown.to_html(index=False, escape=True, border=0, classes="data"))
        body.append(f"<p class='files'>{esc(table.name)}.csv, .md, .tex</p>")
    return PAGE.format(title=esc(heading), body="\n".join(body))


def png_base64(fig) -> str:
    buffer = io.BytesIO()
    with matplotlib.rc_context(STYLE):
        fig.savefig(buffer, format="png", dpi=110, bbox_inches="tight")
    return base64.b64encode(buffer.getvalue()).decode("ascii")


def _numeric(column: pd.Series) -> bool:
    values = [v for v in column if v not in ("", "n/a")]
    return bool(values) and all(_is_number(v) for v in values)


def _is_number(text: str) -> bool:
    try:
        float(str(text).lstrip("<"))
    except ValueError:
        return False
    return True


PAGE = """<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{title}</title>
<style>
body {{ font: 15px/1.5 system-ui, sans-serif; max-width: 62rem; margin: 2rem auto;
        padding: 0 1rem; color: #222; }}
h1 {{ font-size: 1.6rem; }} h2 {{ margin-top: 2rem; border-bottom: 1px solid #ddd; }}
table.data {{ border-collapse: collapse; font-size: 0.85rem; margin: 0.5rem 0; }}
table.data th, table.data td {{ padding: 0.2rem 0.6rem; border-bottom: 1px solid #eee; text-align: right; }}
table.data th {{ border-bottom: 2px solid #999; }}
figure {{ margin: 1rem 0; }} figure img {{ max-width: 100%; }}
figcaption, .files {{ color: #666; font-size: 0.85rem; }}
.methods {{ background: #f6f6f6; padding: 0.8rem; }}
</style></head>
<body>
{body}
</body></html>
"""
