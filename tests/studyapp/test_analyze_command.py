"""The analyze command on exported response tables: outputs, options and clear errors."""

import json
import subprocess
import sys

import pandas as pd
import pytest
from django.core.management import call_command
from django.core.management.base import CommandError

from analysis.simulate import simulate
from analysis.tables import RESPONSE_COLUMNS, write_responses
from tests.conftest import ROOT


@pytest.fixture
def responses(tmp_path):
    table = simulate("fake_or_real", participants=40, trials=4, catch_trials=1, inattentive=0.1, seed=3)
    return write_responses(table, tmp_path / "responses.csv")


def test_analyze_an_exported_table(responses, tmp_path, capsys):
    out = tmp_path / "report"
    call_command("analyze", responses=str(responses), out=str(out), bootstrap=50)
    captured = capsys.readouterr()
    printed = captured.out
    assert "fewer than 10" not in captured.err
    assert "(fake_or_real): " in printed and "Sources by share judged real (best first):" in printed
    summary = json.loads((out / "summary.json").read_text())
    assert summary["order"][0] == "real"
    for name in ("report.html", "sources.csv", "sources.md", "sources.tex", "judged_real.png",
                 "judged_real.svg", "exclusions.csv"):
        assert (out / name).is_file(), name


def test_options_reach_the_analysis(responses, tmp_path):
    out = tmp_path / "report"
    call_command("analyze", responses=str(responses), out=str(out), no_exclusions=True,
                 min_time_factor=0.5, max_failed_catch=2, max_failed_repeats=1, bootstrap=0,
                 real_source="real")
    summary = json.loads((out / "summary.json").read_text())
    assert summary["config"]["exclusions"] is False and summary["config"]["min_time_factor"] == 0.5
    assert summary["config"]["max_failed_catch"] == 2
    assert summary["config"]["max_failed_repeats"] == 1
    # Every interval resamples participants: without the bootstrap there is none.
    assert summary["sources"]["real"]["ci"] == [None, None]
    rules = pd.read_csv(out / "exclusions.csv").set_index("rule")
    assert rules.loc["Analysed", "judgements"] == rules.iloc[0]["judgements"]


def test_too_few_participants_are_noted(tmp_path, capsys):
    table = simulate("fake_or_real", participants=4, trials=4, seed=3)
    path = write_responses(table, tmp_path / "few.csv")
    call_command("analyze", responses=str(path), out=str(tmp_path / "out"), bootstrap=50)
    note = "only 4 participant(s): intervals over participants rest on fewer than 10 people"
    assert f"Note: {note}" in capsys.readouterr().err
    assert note in (tmp_path / "out" / "report.html").read_text()
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert any(n.startswith(note) for n in summary["notes"])


@pytest.mark.parametrize("table, message", [
    (pd.DataFrame(columns=list(RESPONSE_COLUMNS)), "no judgements yet"),
    (simulate("ranking", {"real": 1.0}, participants=3, trials=2), "only one source \\(real\\)"),
    (simulate("ranking", participants=3, trials=2).drop(columns=["rank"]), "needs the column\\(s\\) rank"),
])
def test_bad_tables_give_a_message(table, message, tmp_path):
    path = write_responses(table, tmp_path / "bad.csv")
    with pytest.raises(CommandError, match=f"Cannot analyse bad.csv: .*{message}"):
        call_command("analyze", responses=str(path), out=str(tmp_path / "out"))


def test_missing_file_and_no_traceback(tmp_path):
    with pytest.raises(CommandError, match="no response table at"):
        call_command("analyze", responses=str(tmp_path / "nothing.csv"), out=str(tmp_path / "out"))
    empty = write_responses(pd.DataFrame(columns=list(RESPONSE_COLUMNS)), tmp_path / "empty.csv")
    run = subprocess.run(
        [sys.executable, "manage.py", "analyze", "--responses", str(empty), "--out", str(tmp_path / "o")],
        cwd=ROOT, capture_output=True, text=True, check=False,
    )
    assert run.returncode == 1
    assert "no judgements yet" in run.stderr and "Traceback" not in run.stderr
