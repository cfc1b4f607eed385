"""Simulated raters: the tables they write, and the analysis recovering their strengths."""

import json

import pytest
from scipy import stats as scipy_stats

from analysis.registry import get_analysis, list_analyses
from analysis.report import write_report
from analysis.simulate import simulate, simulated_types
from analysis.study import analyse
from analysis.tables import RESPONSE_COLUMNS, AnalysisError
from tests.analysis.conftest import config

STRENGTHS = {"real": 4.0, "a2m": 3.0, "two_stage_gan": 2.0, "cond_gru": 1.0}
TRUE_ORDER = ["real", "a2m", "two_stage_gan", "cond_gru"]


STUDY_TYPES = simulated_types()


def test_every_analysed_study_type_can_be_simulated():
    assert STUDY_TYPES == list_analyses()


@pytest.mark.parametrize("study_type", STUDY_TYPES)
def test_simulated_table_has_the_response_columns_and_valid_answers(study_type):
    table = simulate(study_type, participants=6, trials=4, catch_trials=1, repeat_trials=2, seed=1)
    plugin = get_analysis(study_type)
    assert list(table.columns) == list(RESPONSE_COLUMNS) + list(plugin.extra_columns) + ["simulated"]
    assert table["simulated"].all()
    assert table.groupby("participant")["trial"].nunique().eq(4 + 1 + 2).all()
    kinds = table.groupby("trial_id")["trial_kind"].first().value_counts().to_dict()
    assert kinds == {"main": 24, "catch": 6, "repeat": 12}
    assert table.loc[table["trial_kind"] == "catch", "is_catch"].sum() == 6
    main = table.loc[table["trial_kind"] == "main"]
    assert main[plugin.answer].notna().all()


@pytest.mark.parametrize("study_type", STUDY_TYPES)
def test_bots_with_known_strengths_are_recovered(study_type, tmp_path):
    """200 simulated participants, 10 % inattentive (they fail the catch trial)."""
    table = simulate(study_type, STRENGTHS, participants=200, trials=8, catch_trials=1,
                     inattentive=0.1, speeders=0.05, seed=7)
    result = analyse(table, config(bootstrap=100))
    write_report(result, tmp_path)
    summary = json.loads((tmp_path / "summary.json").read_text())
    order = [s for s in summary["order"] if s in TRUE_ORDER]  # mushra: also its controls
    tau = scipy_stats.kendalltau([TRUE_ORDER.index(s) for s in order], range(4)).statistic
    assert tau >= 0.9 and len(order) == 4, summary["order"]
    excluded = result.exclusions.set_index("rule").loc["Failed an attention check", "participants"]
    assert excluded == table.loc[table["catch_passed"].eq(False), "participant"].nunique() > 0
    for source, entry in summary["sources"].items():
        assert entry["ci"][0] <= entry["score"] <= entry["ci"][1], source


def test_unknown_study_type_cannot_be_simulated():
    with pytest.raises(AnalysisError, match="cannot simulate 'survey'"):
        simulate("survey")


@pytest.mark.parametrize("study_type", [key for key in simulated_types()
                                        if get_analysis(key).answer == "rating"])
def test_simulated_rating_tables_are_written_and_read_back(study_type, tmp_path):
    """Categorical columns (as simulated rating tables have) are neutralised as text: a
    cell a spreadsheet would run gets its ``'``, the others come back unchanged."""
    import pandas as pd

    from analysis.tables import read_responses, write_responses

    table = simulate(study_type, {"a": 0.5, "b": 0.0}, participants=4, trials=3, seed=1)
    assert any(isinstance(table[c].dtype, pd.CategoricalDtype) for c in table.columns)
    risky = table.copy()
    risky["source"] = pd.Categorical(["=cmd|' /C calc'!A0" if s == "a" else s for s in table["source"]])
    path = write_responses(risky, tmp_path / "responses.csv")
    text = path.read_text()
    assert "'=cmd" in text and "\n=cmd" not in text and ",=cmd" not in text
    back = read_responses(write_responses(table, tmp_path / "plain.csv"))
    assert len(back) == len(table)
    assert sorted(back["source"].astype(str).unique()) == ["a", "b"]
