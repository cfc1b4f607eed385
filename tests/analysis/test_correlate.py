"""Rank correlations of human scores with objective metrics, on tables with known orders."""

import numpy as np
import pandas as pd
import pytest

from analysis.correlate import (
    MIN_SOURCES, correlate, goodness, human_draws, resample_participants,
    write_correlation_report,
)
from analysis.simulate import simulate
from analysis.study import AnalysisConfig, analyse
from analysis.tables import AnalysisError

SOURCES = ["m1", "m2", "m3", "m4", "m5"]


def human(scores):
    score = np.asarray(scores, float)
    return pd.DataFrame({"score": score, "ci_low": score - 0.1, "ci_high": score + 0.1},
                        index=SOURCES[:len(score)])


def test_a_monotone_metric_agrees_perfectly_and_a_reversed_one_by_its_sign():
    people = human([5, 4, 3, 2, 1])
    metrics = pd.DataFrame({
        "accuracy": [0.9, 0.8, 0.5, 0.4, 0.1],  # higher is better: same order as people
        "fid": [1.0, 2.0, 3.0, 10.0, 30.0],  # lower is better: same order once turned
        "mmd_seq": [30.0, 10.0, 3.0, 2.0, 1.0],  # lower is better, but ordered the other way
    }, index=SOURCES)
    result = correlate(people, metrics).table.set_index("metric")
    assert result.loc["accuracy", "spearman"] == pytest.approx(1.0)
    assert result.loc["accuracy", "kendall"] == pytest.approx(1.0)
    assert result.loc["fid", "kendall"] == pytest.approx(1.0)  # lower FID went with higher scores
    assert result.loc["fid", "direction"] == "lower is better"
    assert result.loc["mmd_seq", "kendall"] == pytest.approx(-1.0)
    assert result.loc["mmd_seq", "spearman"] == pytest.approx(-1.0)


def test_closer_to_real_is_better_for_diversity():
    people = human([4, 3, 2, 1])
    metrics = pd.DataFrame({"diversity": [10.0, 8.5, 13.0, 2.0]}, index=SOURCES[:4])
    # distances to the real value 10: 0, 1.5, 3, 8 -> the human order
    result = correlate(people, metrics, real={"diversity": 10.0})
    assert result.table.loc[0, "kendall"] == pytest.approx(1.0)
    assert not result.too_few
    assert [n for n in result.notes if "no ordering can reach" not in n] == []
    with pytest.raises(AnalysisError, match="real clips' value"):
        goodness([1.0], "real")


def test_too_few_sources_say_so():
    result = correlate(human([2, 1, 0]), pd.DataFrame({"fid": [1.0, 2.0, 3.0]}, index=SOURCES[:3]))
    assert result.too_few and len(result.sources) < MIN_SOURCES
    assert any("fewer than 4 sources means next to nothing" in note for note in result.notes)


def test_bootstrap_intervals_pair_human_and_metric_draws(tmp_path):
    rng = np.random.default_rng(0)
    people = human([5, 4, 3, 2, 1])
    metrics = pd.DataFrame({"fid": [1.0, 2.0, 3.0, 4.0, 5.0]}, index=SOURCES)
    draws_h = pd.DataFrame(people["score"].to_numpy() + rng.normal(0, 0.3, (200, 5)), columns=SOURCES)
    draws_m = {"fid": pd.DataFrame(metrics["fid"].to_numpy() + rng.normal(0, 0.3, (200, 5)),
                                   columns=SOURCES)}
    result = correlate(people, metrics, human_draws=draws_h, metric_draws=draws_m)
    row = result.table.iloc[0]
    assert row["spearman"] == pytest.approx(1.0)
    assert -1 <= row["kendall_low"] < row["kendall_high"] <= 1.0
    assert row["kendall_low"] > 0  # the noise is small beside the gaps
    written = write_correlation_report(result, tmp_path / "out")
    names = {p.name for p in written}
    assert {"report.html", "correlations.csv", "correlations.md", "scatter_fid.png",
            "scatter_fid.svg"} <= names
    page = (tmp_path / "out" / "report.html").read_text()
    assert "Too few sources" not in page and "Spearman 1.00" in page
    assert pd.read_csv(tmp_path / "out" / "correlations.csv")["metric"].tolist() == ["fid"]


def test_participant_resamples_rerun_the_analysis():
    table = simulate("ranking", {"real": 3.0, "a": 2.0, "b": 1.0}, participants=12, trials=4, seed=1)
    again = resample_participants(table, np.random.default_rng(0))
    assert again["participant"].nunique() == table["participant"].nunique()
    assert len(again) != len(table) or not again.equals(table)

    def score_of(rows):
        return analyse(rows, AnalysisConfig(bootstrap=0)).analysis.sources["score"]

    draws = human_draws(table, score_of, n=5, seed=0)
    assert draws.shape == (5, 3) and set(draws.columns) == {"real", "a", "b"}
    assert np.isfinite(draws.to_numpy()).all()


def test_exact_permutation_p_values_over_methods():
    import itertools

    from scipy import stats as scipy_stats

    from analysis.correlate import permutation_p, smallest_p

    x, y = [1, 2, 3, 4, 5, 6], [2, 1, 4, 3, 6, 5]
    rho, tau = permutation_p(x, y)
    # Every one of the 720 orders of y, counted by hand with scipy's statistics.
    orders = list(itertools.permutations(y))
    by_hand = np.mean([abs(scipy_stats.spearmanr(x, o).statistic)
                       >= abs(scipy_stats.spearmanr(x, y).statistic) - 1e-12 for o in orders])
    assert rho == pytest.approx(by_hand)
    assert tau == pytest.approx(scipy_stats.kendalltau(x, y, method="exact").pvalue)
    # Four methods in the same order: the best any ordering can do is 2 of 24.
    assert permutation_p([1, 2, 3, 4], [1, 2, 3, 4]) == pytest.approx((2 / 24, 2 / 24))
    assert smallest_p(4) == pytest.approx(2 / 24)


def test_four_methods_say_plainly_that_nothing_can_be_concluded():
    result = correlate(human([4, 3, 2, 1]), pd.DataFrame({"accuracy": [0.9, 0.8, 0.5, 0.1]},
                                                         index=SOURCES[:4]))
    row = result.table.set_index("metric").loc["accuracy"]
    assert row["spearman"] == pytest.approx(1.0) and row["spearman_p"] == pytest.approx(2 / 24)
    assert any("no ordering can reach p < 0.05" in note for note in result.notes)
    five = correlate(human([5, 4, 3, 2, 1]), pd.DataFrame({"accuracy": [0.9, 0.8, 0.5, 0.4, 0.1]},
                                                          index=SOURCES))
    assert five.table["kendall_p"].iloc[0] == pytest.approx(2 / 120)
    assert not any("no ordering can reach" in note for note in five.notes)
