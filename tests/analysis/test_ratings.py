"""Mean ratings, intervals over participants and Mann-Whitney tests against numbers worked out by hand."""

import pytest
from scipy import stats as scipy_stats

from analysis.stats import holm
from analysis.study import analyse
from analysis.tables import AnalysisError
from tests.analysis.conftest import config, make_table, trial

RATINGS = {1: {"real": 5, "a2m": 3, "gru": 1}, 2: {"real": 4, "a2m": 4, "gru": 2},
           3: {"real": 5, "a2m": 2, "gru": 1}}


def ratings_table(study_type="rating_standards", ratings=RATINGS):
    return make_table(study_type, [trial(p, list(clips.items())) for p, clips in ratings.items()])


@pytest.mark.parametrize("study_type", ["rating_standards", "rating_reference"])
def test_mean_ratings_with_intervals_over_participants(study_type):
    sources = analyse(ratings_table(study_type), config()).analysis.sources
    assert list(sources.index) == ["real", "a2m", "gru"]
    assert sources["score"].tolist() == pytest.approx([14 / 3, 3.0, 4 / 3])
    # real is rated 5, 4, 5 by P1, P2, P3. A resample of three participants is all P2
    # (mean 4) with chance 1/27, all P1 or P3 (mean 5) with 8/27, both above 2.5 %: the
    # percentile interval is [4, 5], never beyond what the participants gave.
    interval = sources.loc["real", ["ci_low", "ci_high"]].tolist()
    assert interval == pytest.approx([4.0, 5.0])
    assert sources["n_judgements"].tolist() == [3, 3, 3]


def test_sources_compared_with_mann_whitney_and_holm():
    result = analyse(ratings_table(), config())
    tests = {t.name: t.frame for t in result.tables}["pairwise_tests"].set_index(["a", "b"])
    real, a2m, gru = [5, 4, 5], [3, 4, 2], [1, 2, 1]
    p = [scipy_stats.mannwhitneyu(x, y, alternative="two-sided").pvalue
         for x, y in ((a2m, gru), (a2m, real), (gru, real))]
    assert tests["p"].tolist() == pytest.approx(p)
    assert tests["p_holm"].tolist() == pytest.approx(holm(p))
    # a2m beats gru in 8 of 9 pairs, ties with it in 1: superiority (8 + 0.5) / 9
    assert tests.loc[("a2m", "gru"), "superiority"] == pytest.approx(8.5 / 9)
    kruskal = scipy_stats.kruskal(real, a2m, gru)
    assert result.analysis.tests["kruskal_wallis"]["statistic"] == pytest.approx(kruskal.statistic)


def test_rating_distribution_and_ordinal_agreement():
    result = analyse(ratings_table(), config())
    shares = {t.name: t.frame for t in result.tables}["rating_shares"]
    assert shares.loc["real", ["rating_4", "rating_5"]].tolist() == pytest.approx([1 / 3, 2 / 3])
    assert shares.loc["gru", "rating_1"] == pytest.approx(2 / 3)
    assert result.agreement["level"] == "ordinal" and result.agreement["n_units"] == 3


def test_ratings_outside_the_scale_are_refused():
    table = ratings_table()
    table.loc[0, "rating"] = 6
    with pytest.raises(AnalysisError, match="not whole numbers from 1 to 5"):
        analyse(table, config())
