"""Tables the analysis cannot use are refused with a message naming the problem."""

import pandas as pd
import pytest

from analysis.study import AnalysisConfig, analyse
from analysis.tables import RESPONSE_COLUMNS, AnalysisError
from tests.analysis.conftest import config, make_table, trial

RANKS = [("real", 1), ("a2m", 2)]


def two_participants(study_type="ranking", clips=RANKS):
    return make_table(study_type, [trial(1, clips), trial(2, clips)])


@pytest.mark.parametrize("table", [pd.DataFrame(columns=list(RESPONSE_COLUMNS)), pd.DataFrame(), None])
def test_empty_study(table):
    with pytest.raises(AnalysisError, match="no judgements yet; nothing to analyse"):
        analyse(table)


@pytest.mark.parametrize("study_type, clips", [
    ("ranking", [("real", 1)]), ("rating_standards", [("real", 4)]),
    ("fake_or_real", [("real", True)]), ("pairwise", [("real", None), ("real", None)]),
])
def test_one_source(study_type, clips):
    table = two_participants(study_type, clips)
    table["choice"] = "left"
    with pytest.raises(AnalysisError, match="only one source \\(real\\) was judged"):
        analyse(table, config())


@pytest.mark.parametrize("drop, message", [
    (["source"], "needs the column\\(s\\) source"),
    (["rank"], "needs the column\\(s\\) rank"),
    (["trial_id", "trial"], "trial_id \\(or trial\\)"),
])
def test_missing_columns_are_named(drop, message):
    with pytest.raises(AnalysisError, match=message):
        analyse(two_participants().drop(columns=drop), config())


def test_missing_values():
    table = two_participants()
    table.loc[0, "participant"] = None
    result = analyse(table, config())
    assert "1 row(s) with no participant or source were left out" in result.notes
    unanswered = two_participants()
    unanswered["rank"] = None
    with pytest.raises(AnalysisError, match="no answered main-trial judgements"):
        analyse(unanswered, config())
    no_trials = two_participants()
    no_trials["trial_id"] = None
    no_trials.loc[0, "trial"] = None
    with pytest.raises(AnalysisError, match="no trial_id or trial"):
        analyse(no_trials, config())


def test_everyone_excluded_suggests_no_exclusions():
    table = two_participants()
    table["time_ms"] = 10
    with pytest.raises(AnalysisError, match="left after exclusions .*--no-exclusions"):
        analyse(table, config())
    assert analyse(table, config(exclusions=False)).counts["judgements"] == 4


def test_study_type_problems():
    table = two_participants()
    with pytest.raises(AnalysisError, match="no analysis for study type 'survey'; known types: .*fake_or_real"):
        analyse(table.assign(study_type="survey"))
    mixed = table.copy()
    mixed.loc[0, "study_type"] = "pairwise"
    with pytest.raises(AnalysisError, match="mixes study types \\(pairwise, ranking\\)"):
        analyse(mixed)
    with pytest.raises(AnalysisError, match="no study_type column"):
        analyse(table.drop(columns=["study_type"]))
    named = analyse(table.drop(columns=["study_type"]), config(), study_type="ranking")
    assert named.counts["judgements"] == 4


def test_bad_values():
    table = two_participants()
    table.loc[0, "trial_kind"] = "warmup"
    with pytest.raises(AnalysisError, match="unknown trial_kind warmup"):
        analyse(table, config())
    fractional = two_participants()
    fractional["rank"] = fractional["rank"].astype(float)
    fractional.loc[0, "rank"] = 1.5
    with pytest.raises(AnalysisError, match="not a whole number"):
        analyse(fractional, config())


@pytest.mark.parametrize("changes, message", [
    ({"confidence": 1.5}, "confidence must lie between 0 and 1"),
    ({"min_time_factor": -1}, "min_time_factor must be 0 or more"),
    ({"bootstrap": -5}, "must be 0 or more"),
])
def test_bad_configuration(changes, message):
    with pytest.raises(AnalysisError, match=message):
        AnalysisConfig(**changes)
