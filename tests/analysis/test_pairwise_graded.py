"""Graded pairwise preference: hand counts, both models against a direct maximum-likelihood
fit, the participant bootstrap, known strengths and a known position bias recovered."""

import numpy as np
import pandas as pd
import pytest
from scipy import optimize
from scipy import stats as scipy_stats

from analysis import pairwise_graded as graded
from analysis.simulate import simulate
from analysis.stats import participant_bootstrap
from analysis.study import analyse
from analysis.tables import AnalysisError
from tests.analysis.conftest import config, make_table, trial

# (participant, left, right, answer)
COMPARISONS = [
    (1, "real", "a2m", "left_much"), (1, "a2m", "real", "right"), (1, "real", "a2m", "no_preference"),
    (2, "real", "a2m", "left_slightly"), (2, "a2m", "real", "left_slightly"),
    (2, "a2m", "real", "right_much"), (1, "real", "gru", "left"), (2, "gru", "real", "right_much"),
    (3, "real", "gru", "left_much"), (3, "gru", "real", "right_slightly"),
    (3, "real", "gru", "right_slightly"), (1, "a2m", "gru", "left"), (2, "gru", "a2m", "no_preference"),
    (3, "a2m", "gru", "right"), (3, "a2m", "gru", "both_bad"), (1, "gru", "a2m", "both_bad"),
    (3, "real", "a2m", "left"),
]


def graded_table(comparisons=COMPARISONS):
    table = make_table("pairwise", [
        trial(p, [(left, None, f"{left}-{i}"), (right, None, f"{right}-{i}")], choice=choice)
        for i, (p, left, right, choice) in enumerate(comparisons)
    ])
    table["study_type"] = "pairwise_graded"
    return table


def tables_of(result):
    return {t.name: t.frame for t in result.tables}


def test_per_pair_counts_both_bad_shares_and_raw_position_bias():
    result = analyse(graded_table(), config())
    tables = tables_of(result)
    pairs = tables["pairs"].set_index(["a", "b"])
    # a2m vs real, from a2m's side: real better 5 times (left_much, right, left_slightly
    # with real left, right_much with real right, left with real left), a2m better once
    # (left_slightly with a2m left), one no preference.
    row = pairs.loc[("a2m", "real")]
    assert row[["n", "a_better", "no_preference", "b_better", "both_bad"]].tolist() == [7, 1, 1, 5, 0]
    assert row["mean_grade_a"] == pytest.approx((-3 - 2 - 1 + 1 - 3 + 0 - 2) / 7)
    # The win rate's interval is over participants and clips: at least as wide as the
    # bootstrap of the same share over participants alone, and no binomial test.
    decided = pd.DataFrame({"pcode": [1, 1, 2, 2, 2, 3], "a_won": [0, 0, 0, 1, 0, 0]})
    _, low, high = participant_bootstrap(decided, lambda t: t["a_won"].mean(),
                                         n=config().bootstrap, seed=config().seed)
    assert row["ci_low"] <= low and row["ci_high"] >= high
    assert row["ci_low"] <= 1 / 6 <= row["ci_high"]
    assert row["p"] != pytest.approx(scipy_stats.binomtest(1, 6, 0.5).pvalue)
    assert (pairs["p_holm"] >= pairs["p"]).all()
    assert len(tables["differences"]) == 3
    assert pairs.loc[("a2m", "gru"), ["a_better", "no_preference", "b_better", "both_bad"]].tolist() == [
        1, 1, 1, 2]
    sources = result.analysis.sources
    assert sources.loc["gru", "both_bad"] == 2 and sources.loc["real", "both_bad"] == 0
    assert sources.loc["a2m", "both_bad_share"] == pytest.approx(2 / 12)
    assert sources.loc["gru", "both_bad_share"] == pytest.approx(2 / 10)
    bias = tables["position_bias"].set_index("measure")
    directional = [c for *_, c in COMPARISONS if c not in ("both_bad", "no_preference")]
    left = sum(c.startswith("left") for c in directional)
    raw = bias.loc["share of directional answers favouring the left clip"]
    assert (raw["estimate"], raw["n"]) == (pytest.approx(left / len(directional)), len(directional))
    assert result.analysis.tests["n_both_bad"] == 2 and result.analysis.tests["n_ties"] == 2
    assert any("descriptive" in m for m in result.analysis.methods)


def test_fewer_than_ten_participants_are_noted():
    result = analyse(graded_table(), config())
    assert any("fewer than 10 participants" in note for note in result.notes)
    many = [(10 + i, *rest) for i, (_, *rest) in enumerate(COMPARISONS * 2)][:20]
    result = analyse(graded_table(many), config())
    assert not any("fewer than 10 participants" in note for note in result.notes)


def _counts(comparisons, names):
    """Return ``{(left, right): grade counts (7,)}`` of the graded answers."""
    out = {}
    for _, left, right, choice in comparisons:
        if choice == "both_bad":
            continue
        cell = out.setdefault((names.index(left), names.index(right)), np.zeros(7))
        cell[graded.GRADE[choice] + 3] += 1
    return out


def test_the_ordinal_model_is_the_penalised_maximum_likelihood_fit():
    result = analyse(graded_table(), config(bootstrap=0))
    names = ["a2m", "gru", "real"]
    cells = _counts(COMPARISONS, names)

    def loss(phi):
        theta, beta, distances = phi[:3], phi[3], np.cumsum(np.exp(phi[4:]))
        cuts = np.concatenate([-distances[::-1], distances])  # symmetric, as the scale
        total = -0.5 * (np.sum(theta**2) + beta**2) / graded.PRIOR_SD**2
        for (i, j), counts in list(cells.items()) + [((None, None), np.full(7, graded.CUT_PSEUDO))]:
            eta = 0.0 if i is None else theta[i] - theta[j] + beta
            cdf = np.concatenate([[0], scipy_stats.logistic.cdf(cuts - eta), [1]])
            total += counts @ np.log(np.diff(cdf))
        return -total

    start = np.concatenate([np.zeros(4), np.log([0.5, 1.0, 1.0])])
    best = optimize.minimize(loss, start, method="BFGS", options={"gtol": 1e-9}).x
    sources = result.analysis.sources
    expected = best[:3] - best[:3].mean()
    assert sources.loc[names, "score"].tolist() == pytest.approx(expected.tolist(), abs=1e-4)
    bias = tables_of(result)["position_bias"].set_index("measure")
    assert bias.loc["ordinal shift beta (logit)", "estimate"] == pytest.approx(best[3], abs=1e-4)
    assert np.isnan(sources["ci_low"]).all()  # no bootstrap, no interval


def test_davidsons_model_is_the_penalised_maximum_likelihood_fit():
    result = analyse(graded_table(), config(bootstrap=0))
    names = ["a2m", "gru", "real"]
    cells = _counts(COMPARISONS, names)

    def loss(phi):
        theta, log_g, log_nu = phi[:3], phi[3], phi[4]
        total = -0.5 * (np.sum(theta**2) + log_g**2 + log_nu**2) / graded.PRIOR_SD**2
        for (i, j), counts in cells.items():
            a, tie, b = (np.exp(theta[i] + log_g), np.exp(log_nu + (theta[i] + theta[j]) / 2),
                         np.exp(theta[j]))
            won_b, tied, won_a = counts[:3].sum(), counts[3], counts[4:].sum()
            total += (won_a * np.log(a) + tied * np.log(tie) + won_b * np.log(b)
                      - counts.sum() * np.log(a + tie + b))
        return -total

    best = optimize.minimize(loss, np.zeros(5), method="BFGS", options={"gtol": 1e-9}).x
    sources = result.analysis.sources
    expected = best[:3] - best[:3].mean()
    assert sources.loc[names, "davidson"].tolist() == pytest.approx(expected.tolist(), abs=1e-4)
    bias = tables_of(result)["position_bias"].set_index("measure")
    assert bias.loc["Davidson log order effect", "estimate"] == pytest.approx(best[3], abs=1e-4)


def test_intervals_resample_participants_not_judgements():
    """Two people who disagree completely, each many times: judgement by judgement the
    data look sure of a tie; over participants they are not."""
    comparisons = ([(1, "a", "b", "left_much"), (1, "b", "a", "right_much")] * 20
                   + [(2, "a", "b", "right_much"), (2, "b", "a", "left_much")] * 20)
    result = analyse(graded_table(comparisons), config(bootstrap=200))
    a = result.analysis.sources.loc["a"]
    assert abs(a["score"]) < 0.05
    assert a["ci_low"] < -1 and a["ci_high"] > 1  # a replicate may hold only one of them


def test_an_unknown_answer_is_refused():
    table = graded_table()
    table.loc[0:1, "choice"] = "maybe"
    with pytest.raises(AnalysisError, match="unknown choice.*maybe.*expected left_much"):
        analyse(table, config())


STRENGTHS = {"real": 4.0, "a2m": 3.0, "two_stage_gan": 2.0, "cond_gru": 1.0}
TRUE_ORDER = list(STRENGTHS)


def tau(order):
    return scipy_stats.kendalltau([TRUE_ORDER.index(s) for s in order], range(len(order))).statistic


def test_bots_of_known_strengths_are_recovered_by_every_score():
    table = simulate("pairwise_graded", STRENGTHS, participants=200, trials=8, catch_trials=1,
                     inattentive=0.1, seed=3)
    sources = analyse(table, config(bootstrap=100)).analysis.sources
    for column in ("score", "davidson", "elo"):
        assert tau(sources.sort_values(column, ascending=False).index) >= 0.9, column
    # Effects on the simulation's own scale: 1 apart per step of strength (noise 1).
    gaps = np.diff(sources.loc[TRUE_ORDER, "score"].to_numpy())
    assert gaps == pytest.approx([-1, -1, -1], abs=0.25)
    # "Both bad" is said of the weaker pairs only.
    shares = sources["both_bad_share"]
    assert shares["cond_gru"] > shares["real"]


@pytest.mark.parametrize("bias", [0.0, 0.8])
def test_a_known_position_bias_is_recovered(bias):
    # Without clip effects the simulated raters follow the ordinal model exactly (clip
    # effects would add latent noise and shrink every estimate a little).
    table = simulate("pairwise_graded", STRENGTHS, participants=200, trials=10,
                     position_bias=bias, tie_rate=0.0, clip_sd=0.0, seed=11)
    result = analyse(table, config(bootstrap=200))
    rows = tables_of(result)["position_bias"].set_index("measure")
    shift = rows.loc["ordinal shift beta (logit)"]
    assert shift["ci_low"] <= bias <= shift["ci_high"]
    assert shift["estimate"] == pytest.approx(bias, abs=0.15)
    davidson = rows.loc["Davidson log order effect"]
    raw = rows.loc["share of directional answers favouring the left clip"]
    if bias:
        assert davidson["ci_low"] > 0 and raw["ci_low"] > 0.5 and raw["p"] < 0.001
    else:
        assert davidson["ci_low"] <= 0 <= davidson["ci_high"]
        assert raw["ci_low"] <= 0.5 <= raw["ci_high"]


def test_simulated_trials_show_a_left_and_a_right_clip():
    table = simulate("pairwise_graded", participants=6, trials=4, catch_trials=1,
                     repeat_trials=2, seed=1)
    main = table.loc[table["trial_kind"] == "main"]
    assert set(main.groupby("trial_id")["position"].apply(lambda p: tuple(sorted(p)))) == {(0, 1)}
