"""Pairwise win rates, Bradley-Terry worths and position bias against hand counts."""

import numpy as np
import pytest
from scipy import stats as scipy_stats

from analysis import worth
from analysis.study import analyse
from analysis.tables import AnalysisError
from tests.analysis.conftest import config, make_table, trial

# (participant, left, right, choice). Decided: real over a2m 4-2, real over gru 4-1,
# a2m over gru 2-1 (the counts of worths 4, 2, 1); one tie of each kind.
COMPARISONS = [
    (1, "real", "a2m", "left"), (1, "a2m", "real", "right"), (1, "real", "a2m", "right"),
    (2, "real", "a2m", "left"), (2, "a2m", "real", "right"), (2, "a2m", "real", "left"),
    (1, "real", "gru", "left"), (2, "gru", "real", "right"), (3, "real", "gru", "left"),
    (3, "gru", "real", "right"), (3, "real", "gru", "right"),
    (1, "a2m", "gru", "left"), (2, "gru", "a2m", "right"), (3, "a2m", "gru", "right"),
    (3, "real", "a2m", "both_good"), (1, "a2m", "gru", "both_bad"),
]


def pairwise_table(comparisons=COMPARISONS):
    return make_table("pairwise", [
        trial(p, [(left, None, f"{left}-{i}"), (right, None, f"{right}-{i}")], choice=choice)
        for i, (p, left, right, choice) in enumerate(comparisons)
    ])


def test_win_rates_with_intervals_over_participants_and_ties():
    tables = {t.name: t.frame for t in analyse(pairwise_table(), config()).tables}
    rates = tables["win_rates"].set_index(["a", "b"])
    row = rates.loc[("a2m", "real")]
    assert row[["wins_a", "wins_b", "both_good", "both_bad"]].tolist() == [2, 4, 1, 0]
    assert row["win_rate_a"] == pytest.approx(2 / 6)
    # P1 and P2 each gave a2m 1 of 3 wins against real (P3 tied): every resample of
    # participants gives 1/3; but every clip was shown once, so drawing clips again
    # changes the comparisons, and the interval over participants and clips is wide.
    assert row["ci_low"] < 1 / 3 < row["ci_high"] and row["ci_high"] - row["ci_low"] > 0.3
    assert 0 <= row["ci_low"] and row["ci_high"] <= 1
    # The test is the crossed t test, not a binomial test of six comparisons.
    assert row["p"] != pytest.approx(scipy_stats.binomtest(2, 6, 0.5).pvalue)
    assert row["p_holm"] >= row["p"]
    assert rates.loc[("a2m", "gru"), ["wins_a", "wins_b", "both_bad"]].tolist() == [2, 1, 1]


def test_bradley_terry_worth_is_the_fit_of_decided_comparisons():
    result = analyse(pairwise_table(), config())
    pairs = np.array([[0, 1], [1, 0], [0, 2], [2, 0], [1, 2], [2, 1]])  # real, a2m, gru
    expected = worth.fit(pairs, np.array([4, 2, 4, 1, 2, 1]), 3)
    sources = result.analysis.sources
    assert list(sources.index) == ["real", "a2m", "gru"]
    assert sources["score"].tolist() == pytest.approx(expected.tolist())
    # Without the prior the worths are exactly 4 : 2 : 1.
    assert worth.fit(pairs, np.array([4, 2, 4, 1, 2, 1]), 3, prior=0) == pytest.approx(
        np.log([4, 2, 1]) - np.log([4, 2, 1]).mean())
    assert sources.loc["real", "win_rate"] == pytest.approx(8 / 11)
    assert result.analysis.tests["ties"] == 2


def test_position_bias_counts_left_wins():
    bias = analyse(pairwise_table(), config()).analysis.tests["position_bias"]
    left = sum(1 for *_, choice in COMPARISONS if choice == "left")
    assert (bias["left"], bias["n_decided"]) == (left, 14)
    assert bias["share_left"] == pytest.approx(left / 14)
    assert 0 < bias["p"] <= 1
    assert bias["ci_low"] <= bias["share_left"] <= bias["ci_high"]


def test_agreement_is_nominal_over_pairs_of_clips():
    # The same two clips judged by three participants, shown either way round.
    comparisons = [(1, "real", "a2m", "left"), (2, "a2m", "real", "right"), (3, "real", "a2m", "right")]
    table = make_table("pairwise", [trial(p, [(l, None, l), (r, None, r)], choice=c)
                                    for p, l, r, c in comparisons])
    result = analyse(table, config())
    # In a2m-first order the values are second, second, first. Coincidences: o(s, s) = 1,
    # o(s, f) = o(f, s) = 1; n_s = 2, n_f = 1: alpha = 1 - (3 - 1) * 2 / (2 * 2 * 1) = 0.
    assert result.agreement["n_units"] == 1 and result.agreement["n_values"] == 3
    assert result.agreement["alpha"] == pytest.approx(0.0)


def test_unknown_choices_and_lone_clips():
    table = pairwise_table()
    table["choice"] = table["choice"].astype(object)
    table.loc[0:1, "choice"] = "neither"
    with pytest.raises(AnalysisError, match="unknown choice\\(s\\) neither"):
        analyse(table, config())
    lonely = pairwise_table().drop(index=0)
    result = analyse(lonely, config())
    assert any("without exactly one left" in note for note in result.notes)
    assert result.counts["trials"] == len(COMPARISONS) - 1


def test_simulated_trials_show_a_left_and_a_right_clip():
    from analysis.simulate import simulate

    table = simulate("pairwise", participants=6, trials=4, catch_trials=1, repeat_trials=2, seed=1)
    main = table.loc[table["trial_kind"] == "main"]
    assert set(main.groupby("trial_id")["position"].apply(lambda p: tuple(sorted(p)))) == {(0, 1)}
