"""Fake-or-real shares, tests against the real rate and d' against counts done by hand."""

import numpy as np
import pytest
from scipy import stats as scipy_stats

from analysis.stats import holm
from analysis.study import analyse
from analysis.tables import AnalysisError
from tests.analysis.conftest import config, make_table, trial

# participant, action, judged real per clip (two clips per source, numbered 0 and 1)
ANSWERS = [
    (1, "eat", {"real": (True, True), "a2m": (True, False), "gru": (False, False)}),
    (1, "walk", {"real": (True, False), "a2m": (True, True), "gru": (False, True)}),
    (2, "eat", {"real": (True, True), "a2m": (False, False), "gru": (False, False)}),
    (2, "walk", {"real": (True, True), "a2m": (True, False), "gru": (True, False)}),
]


def fake_or_real_table(answers=ANSWERS):
    return make_table("fake_or_real", [
        trial(participant, [(source, value, f"{action}-{source}-{i}")
                            for source, values in clips.items() for i, value in enumerate(values)],
              action=action)
        for participant, action, clips in answers
    ])


def test_shares_with_intervals_over_participants():
    # real 7 of 8, a2m 4 of 8, gru 2 of 8
    sources = analyse(fake_or_real_table(), config()).analysis.sources
    assert list(sources.index) == ["real", "a2m", "gru"]
    assert sources["score"].tolist() == pytest.approx([7 / 8, 4 / 8, 2 / 8])
    assert sources["judged_real"].tolist() == [7, 4, 2]
    # a2m: P1 called 3 of 4 clips real, P2 1 of 4: the interval reaches past both ways
    # (clips drawn again too), cut to 0..1.
    low, high = sources.loc["a2m", ["ci_low", "ci_high"]].tolist()
    assert 0 <= low < 0.5 < high <= 1
    assert sources["n_participants"].tolist() == [2, 2, 2]


def test_generated_sources_are_tested_against_the_real_rate_over_clips():
    result = analyse(fake_or_real_table(), config())
    sources = result.analysis.sources
    binomial = [scipy_stats.binomtest(4, 8, 7 / 8).pvalue, scipy_stats.binomtest(2, 8, 7 / 8).pvalue]
    p = sources.loc[["a2m", "gru"], "p"].to_numpy()
    # The real rate is an estimate too and the answers are alike within participants and
    # clips: the crossed test is far less sure than the binomial one.
    assert np.all(p > np.array(binomial))
    assert sources.loc[["a2m", "gru"], "p_holm"].tolist() == pytest.approx(holm(p))
    assert np.isnan(sources.loc["real", "p"])
    assert sources.loc["gru", "difference"] == pytest.approx(2 / 8 - 7 / 8)
    # Tested on the clips' mean log-odds (0.5 added to both counts of each clip): gru's
    # clips were called real 0, 0, 1 and 1 times of 2, the real ones 2, 2, 2 and 1.
    by_hand = np.mean([np.log(0.5 / 2.5)] * 2 + [0.0] * 2) - np.mean([np.log(2.5 / 0.5)] * 3 + [0.0])
    assert sources.loc["gru", "log_odds_difference"] == pytest.approx(by_hand)
    assert sources.loc["gru", "diff_ci_low"] < by_hand < sources.loc["gru", "diff_ci_high"]
    differences = {t.name: t.frame for t in result.tables}["differences"].set_index(["a", "b"])
    assert differences.loc[("gru", "real"), "difference"] == pytest.approx(by_hand)
    assert differences.loc[("gru", "real"), "p"] == pytest.approx(sources.loc["gru", "p"])


def test_dprime_per_participant_with_log_linear_correction():
    result = analyse(fake_or_real_table(), config())
    per_participant = {t.name: t.frame for t in result.tables}["dprime"].set_index("participant")
    z = scipy_stats.norm.ppf
    # P1: 3 of 4 real clips called real, 4 of 8 generated; P2: 4 of 4 and 2 of 8.
    expected = {1: z(3.5 / 5) - z(4.5 / 9), 2: z(4.5 / 5) - z(2.5 / 9)}
    assert per_participant["dprime"].to_dict() == pytest.approx(expected)
    assert per_participant.loc[1, ["hits", "n_real", "false_alarms", "n_generated"]].tolist() == [3, 4, 4, 8]
    overall = result.analysis.tests["dprime"]["overall"]
    assert overall["mean"] == pytest.approx(np.mean(list(expected.values()))) and overall["n"] == 2
    by_source = {row["source"]: row for row in result.analysis.tests["dprime"]["by_source"]}
    # a2m alone: P1 false alarms 3 of 4, P2 1 of 4.
    a2m = np.mean([z(3.5 / 5) - z(3.5 / 5), z(4.5 / 5) - z(1.5 / 5)])
    assert by_source["a2m"]["mean_dprime"] == pytest.approx(a2m)


def test_agreement_is_nominal_over_clips():
    result = analyse(fake_or_real_table(), config())
    assert result.agreement["level"] == "nominal"
    assert result.agreement["n_units"] == 12 and result.agreement["n_values"] == 24


def test_without_a_real_source_the_tests_are_skipped_with_a_note():
    result = analyse(fake_or_real_table(), config(real_source="ground_truth"))
    assert "p" not in result.analysis.sources.columns
    assert any("no source is called 'ground_truth'" in note for note in result.notes)


def test_answers_must_be_true_or_false():
    table = fake_or_real_table()
    table["judged_real"] = table["judged_real"].astype(object)
    table.loc[0, "judged_real"] = "maybe"
    with pytest.raises(AnalysisError, match="judged_real must be true/false or empty; found maybe"):
        analyse(table, config())
