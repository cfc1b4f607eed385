"""Write a study result to a folder: HTML report, tables, figures and ``summary.json``.

    out/report.html        self-contained: figures embedded as PNG, every table, methods
    out/summary.json       per source: score, interval, N; the order of sources
    out/<table>.csv|.md|.tex
    out/<figure>.png|.svg
    out/supplement.html    one page for a paper's supplement: the headline figure and table
    out/supplement.pdf     the same page as a PDF (matplotlib)
    out/headline_<name>.tex  one booktabs LaTeX table per headline result: the sources'
                           scores and, where tested, their differences, each estimate
                           [low, high] rounded alike
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
from analysis.formatting import (display_frame, estimate_with_interval, interval, number,
                                 p_value, plural)
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
    for name, text in headline_latex(result).items():
        path = out / f"headline_{name}.tex"
        path.write_text(text)
        written.append(path)
    written += write_supplement(result, out, figures, title)
    return written


# --- headline results: LaTeX tables and the one-page supplement ----------------------------

def headline_digits(*columns) -> int:
    """Return the decimals of a headline table: 1 for numbers of 10 or more (a 0-100
    score), else 2; one precision for a column's estimates and intervals alike."""
    values = pd.concat([pd.to_numeric(pd.Series(c), errors="coerce") for c in columns]).abs()
    values = values[values.notna() & (values != float("inf"))]
    return 1 if len(values) and values.max() >= 10 else 2


def headline_sources(result) -> pd.DataFrame:
    """Return the headline table: per source (best first) its score with the interval,
    participants and judgements, as strings."""
    sources = result.analysis.sources
    digits = headline_digits(sources["score"], sources["ci_low"], sources["ci_high"])
    ci = f"{result.config.confidence:.0%}"
    return pd.DataFrame({
        "Source": [str(s) for s in sources.index],
        f"{result.analysis.measure} [{ci} CI]": [
            estimate_with_interval(r["score"], r["ci_low"], r["ci_high"], digits)
            for _, r in sources.iterrows()],
        "Participants": [str(int(n)) for n in sources["n_participants"]],
        "Judgements": [str(int(n)) for n in sources["n_judgements"]],
    })


def headline_differences(result) -> pd.DataFrame | None:
    """Return the tested differences between sources (a - b, interval, Holm p), as
    strings, or None when the analysis tested none."""
    frame = (result.analysis.tests or {}).get("differences")
    if not isinstance(frame, pd.DataFrame) or frame.empty or "difference" not in frame.columns:
        return None
    digits = headline_digits(frame["difference"], frame["ci_low"], frame["ci_high"])
    ci = f"{result.config.confidence:.0%}"
    holm = "p_holm" if "p_holm" in frame.columns else "p"
    return pd.DataFrame({
        "Comparison": [f"{a} - {b}" for a, b in zip(frame["a"], frame["b"])],
        f"Difference [{ci} CI]": [
            estimate_with_interval(r["difference"], r["ci_low"], r["ci_high"], digits)
            for _, r in frame.iterrows()],
        "p (Holm)" if holm == "p_holm" else "p": [p_value(v) for v in frame[holm]],
    })


def _headline_caption(result, what: str) -> str:
    counts = result.counts
    caption = (f"{what} ({result.study or 'study'}, {result.study_type.replace('_', ' ')}"
               + (f", question '{result.criterion}'" if result.criterion else "")
               + f"): {plural(counts['participants'], 'participant')}, "
               f"{plural(counts['judgements'], 'judgement')}; intervals over participants"
               + (" and clips" if result.config.random_clips else " (clips held fixed)"))
    if counts.get("simulated"):
        n = counts["simulated"]
        caption += ("; SIMULATED: every participant was a bot" if n == counts["participants"]
                    else f"; SIMULATED: {n} of the participants {'was a bot' if n == 1 else 'were bots'}")
    return caption


def headline_latex(result) -> dict[str, str]:
    """Return ``{name: LaTeX}``: one booktabs table per headline result."""
    out = {"sources": latex_table(headline_sources(result),
                                  _headline_caption(result, _capital(result.analysis.measure)
                                                    + " per source"),
                                  label=f"tab:{_label(result)}-sources")}
    differences = headline_differences(result)
    if differences is not None:
        out["differences"] = latex_table(
            differences, _headline_caption(result, "Differences between sources"),
            label=f"tab:{_label(result)}-differences")
    return {name: "% needs \\usepackage{booktabs}\n" + text for name, text in out.items()}


def _capital(text: str) -> str:
    return text[:1].upper() + text[1:]


def _label(result) -> str:
    name = "-".join(filter(None, [result.study, result.criterion])) or result.study_type
    return re.sub(r"[^A-Za-z0-9-]+", "-", name).strip("-") or "study"


def write_supplement(result, out: Path, figures, title: str | None = None) -> list[Path]:
    """Write ``supplement.html`` and ``supplement.pdf``: one page with the headline figure
    (the analysis's first) and table, for a paper's supplement."""
    html_path = out / "supplement.html"
    html_path.write_text(render_supplement(result, figures[:1], title))
    written = [html_path]
    pdf = out / "supplement.pdf"
    # No creation date: the same result writes the same file.
    supplement_figure(result, title).savefig(pdf, format="pdf", metadata={"CreationDate": None})
    written.append(pdf)
    return written


def _supplement_heading(result, title) -> str:
    return title or f"{result.study or 'Study'} ({result.study_type.replace('_', ' ')})"


def render_supplement(result, figures, title: str | None = None) -> str:
    """Return the one-page supplement as self-contained HTML."""
    from analysis.writeup import simulated_banner

    esc = html.escape
    body = [f"<h1>{esc(_supplement_heading(result, title))}</h1>"]
    banner = simulated_banner(result)
    if banner:
        body.append(f"<p class='simulated'>{esc(banner)}.</p>")
    for plot, data in figures:
        body.append(f"<figure><img alt='{esc(plot.title)}' src='data:image/png;base64,{data}'>"
                    f"<figcaption>{esc(plot.title)}</figcaption></figure>")
    body.append(f"<p class='caption'>{esc(_headline_caption(result, _capital(result.analysis.measure) + ' per source'))}.</p>")
    body.append(headline_sources(result).to_html(index=False, escape=True, border=0,
                                                 classes="data"))
    differences = headline_differences(result)
    if differences is not None:
        body.append("<p class='caption'>Differences between sources (Holm-corrected).</p>")
        body.append(differences.to_html(index=False, escape=True, border=0, classes="data"))
    return SUPPLEMENT.format(title=esc(_supplement_heading(result, title)), body="\n".join(body))


def supplement_figure(result, title: str | None = None):
    """Return the supplement page (A4 portrait) as a matplotlib ``Figure``: the headline
    figure above the headline table (and the differences, when tested)."""
    import matplotlib.image
    from matplotlib.backends.backend_pdf import FigureCanvasPdf
    from matplotlib.figure import Figure

    from analysis.writeup import simulated_banner

    with matplotlib.rc_context(STYLE):
        page = Figure(figsize=(8.27, 11.69))
        FigureCanvasPdf(page)
        page.text(0.06, 0.965, _supplement_heading(result, title), fontsize=13,
                  weight="bold", va="top", parse_math=False)
        banner = simulated_banner(result)
        if banner:
            page.text(0.06, 0.94, _wrap(banner + ".", 100), fontsize=9, color="#b00020",
                      va="top", weight="bold")
        top = 0.90
        if result.analysis.plots:
            plot = result.analysis.plots[0]
            image = matplotlib.image.imread(io.BytesIO(base64.b64decode(
                png_base64(plot.draw()))), format="png")
            height = min(0.42, 0.88 * image.shape[0] / image.shape[1] * 8.27 / 11.69)
            ax = page.add_axes([0.06, top - height, 0.88, height])
            ax.imshow(image)
            ax.set_axis_off()
            page.text(0.06, top - height - 0.01, plot.title, fontsize=8, color="#555",
                      va="top", parse_math=False)
            top -= height + 0.04
        tables = [(headline_sources(result), _headline_caption(
            result, _capital(result.analysis.measure) + " per source"))]
        differences = headline_differences(result)
        if differences is not None:
            tables.append((differences, "Differences between sources (Holm-corrected)"))
        for frame, caption in tables:
            rows = min(len(frame), 18)
            height = 0.022 * (rows + 1)
            page.text(0.06, top, _wrap(caption + ".", 110), fontsize=8, va="top",
                      parse_math=False)
            top -= 0.03
            if top - height < 0.03:
                break
            ax = page.add_axes([0.06, top - height, 0.88, height])
            ax.set_axis_off()
            cells = frame.head(rows)
            widths = [max([len(str(c))] + [len(str(v)) for v in cells[c]]) + 2
                      for c in cells.columns]
            table = ax.table(cellText=cells.to_numpy().tolist(), colLabels=list(cells.columns),
                             colWidths=[w / sum(widths) for w in widths], loc="upper left",
                             cellLoc="left", colLoc="left", edges="horizontal")
            table.auto_set_font_size(False)
            table.set_fontsize(8)
            for cell in table.get_celld().values():
                cell.get_text().set_parse_math(False)  # a source named "$x$" stays as typed
            top -= height + 0.04
    return page


def _wrap(text: str, width: int) -> str:
    import textwrap

    return "\n".join(textwrap.wrap(text, width))


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
    from analysis.writeup import simulated_banner

    heading = title or f"{result.study or 'Study'} ({result.study_type})"
    counts = result.counts
    body = [f"<h1>{esc(heading)}</h1>"]
    banner = simulated_banner(result)
    if banner:
        body.append(f"<p class='simulated'>{esc(banner)}.</p>")
    body.append(f"<p class='lead'>{plural(counts['participants'], 'participant')}, "
                f"{plural(counts['judgements'], 'judgement')}, {plural(counts['trials'], 'trial')}. "
                f"Measure: {esc(result.analysis.measure)}. One-page supplement: "
                f"<a href='supplement.html'>supplement.html</a>, "
                f"<a href='supplement.pdf'>supplement.pdf</a>; LaTeX: headline_*.tex.</p>")
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
.simulated {{ background: #fde8ec; border-left: 4px solid #b00020; padding: 0.6rem 0.8rem;
              font-weight: bold; }}
</style></head>
<body>
{body}
</body></html>
"""

SUPPLEMENT = """<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{title}</title>
<style>
@page {{ size: A4; margin: 15mm; }}
body {{ font: 11px/1.4 system-ui, sans-serif; max-width: 180mm; margin: 1rem auto; color: #222; }}
h1 {{ font-size: 1.2rem; margin: 0 0 0.5rem; }}
figure {{ margin: 0.5rem 0; }} figure img {{ max-width: 100%; max-height: 120mm; }}
figcaption, .caption {{ color: #444; font-size: 0.85rem; }}
table.data {{ border-collapse: collapse; margin: 0.3rem 0 0.8rem; }}
table.data th, table.data td {{ padding: 0.15rem 0.6rem; text-align: left; }}
table.data thead th {{ border-top: 1.5px solid #000; border-bottom: 1px solid #000; }}
table.data tbody tr:last-child td {{ border-bottom: 1.5px solid #000; }}
.simulated {{ color: #b00020; font-weight: bold; }}
</style></head>
<body>
{body}
</body></html>
"""
