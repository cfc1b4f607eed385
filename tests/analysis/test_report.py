"""The report of every study type: HTML, tables in three formats, figures, summary.json."""

import json
import re

import pandas as pd
import pytest

from analysis.registry import list_analyses
from analysis.report import latex_table, markdown_table, write_report
from analysis.simulate import simulate
from analysis.study import analyse
from tests.analysis.conftest import config


@pytest.fixture(scope="module", params=list_analyses())
def report(request, tmp_path_factory):
    out = tmp_path_factory.mktemp(request.param)
    table = simulate(request.param, participants=30, trials=4, catch_trials=1, repeat_trials=1,
                     inattentive=0.1, seed=2)
    result = analyse(table, config(bootstrap=50))
    written = write_report(result, out, title=f"Test {request.param}")
    return result, out, written


def test_every_table_is_written_as_csv_markdown_and_latex(report):
    result, out, _ = report
    assert {"sources", "exclusions", "agreement"} <= {t.name for t in result.tables}
    for table in result.tables:
        csv = pd.read_csv(out / f"{table.name}.csv")
        assert len(csv) == len(table.frame), table.name
        markdown = (out / f"{table.name}.md").read_text()
        assert markdown.startswith(f"**{table.title}**") and "| ---" in markdown.replace(":---", "---")
        latex = (out / f"{table.name}.tex").read_text()
        assert r"\begin{tabular}" in latex and r"\toprule" in latex and r"\bottomrule" in latex


def test_every_figure_is_written_as_png_and_svg(report):
    result, out, _ = report
    assert result.analysis.plots
    for plot in result.analysis.plots:
        assert (out / f"{plot.name}.png").read_bytes().startswith(b"\x89PNG")
        assert "<svg" in (out / f"{plot.name}.svg").read_text()


def test_html_is_self_contained_with_tables_figures_and_methods(report):
    result, out, _ = report
    page = (out / "report.html").read_text()
    assert page.count("data:image/png;base64,") == len(result.analysis.plots)
    assert page.count("<table") == len(result.tables)
    for table in result.tables:
        assert table.title.replace("'", "&#x27;") in page
    for source in result.analysis.sources.index:
        assert f"<b>{source}</b>" in page
    assert "Krippendorff" in page and "Holm" in page
    assert "<script" not in page and "http" not in page.split("</style>")[1]


def test_summary_json_gives_score_interval_and_n_per_source(report):
    result, out, _ = report
    summary = json.loads((out / "summary.json").read_text())
    assert summary["study_type"] == result.study_type
    assert summary["order"] == list(result.analysis.sources.index)
    assert set(summary["sources"]) == set(summary["order"])
    for entry in summary["sources"].values():
        assert set(entry) == {"score", "ci", "n_participants", "n_judgements"}
        assert entry["n_judgements"] > 0 and len(entry["ci"]) == 2
    assert summary["n_judgements"] == sum(e["n_judgements"] for e in summary["sources"].values())


ESTIMATE = re.compile(r"(-?\d+(?:\.(\d+))?) \[(-?\d+(?:\.(\d+))?), (-?\d+(?:\.(\d+))?)\]")


def test_supplement_page_and_a_latex_table_per_headline_result(report):
    result, out, written = report
    page = (out / "supplement.html").read_text()
    assert page.count("data:image/png;base64,") == 1 and "<script" not in page
    assert "These data are simulated" in page  # simulate's rows are marked simulated
    assert (out / "supplement.pdf").read_bytes().startswith(b"%PDF")
    latex = (out / "headline_sources.tex").read_text()
    assert r"\toprule" in latex and r"\bottomrule" in latex and "SIMULATED" in latex
    names = ["headline_sources.tex"] + (
        ["headline_differences.tex"] if (out / "headline_differences.tex").exists() else [])
    assert {out / name for name in names} <= set(written)
    for name in names:
        found = ESTIMATE.findall((out / name).read_text())
        assert found, name
        for value, d1, low, d2, high, d3 in found:
            assert len(d1) == len(d2) == len(d3), (name, value, low, high)  # one precision


def test_the_report_header_says_the_participants_were_simulated(report):
    _, out, _ = report
    head = (out / "report.html").read_text().split("<h2>", 1)[0]
    assert "class='simulated'" in head and "were bots" in head


def test_markdown_and_latex_writers():
    shown = pd.DataFrame({"source": ["a_b", "c&d"], "share": ["0.500", "<0.001"]})
    assert markdown_table(shown).splitlines()[:3] == [
        "| source | share |", "| :--- | ---: |", "| a_b | 0.500 |"]
    latex = latex_table(shown, "Shares: 50%", label="tab:x")
    assert r"\caption{Shares: 50\%}" in latex and r"\begin{tabular}{lr}" in latex
    assert r"a\_b & 0.500 \\" in latex and r"c\&d & <0.001 \\" in latex
