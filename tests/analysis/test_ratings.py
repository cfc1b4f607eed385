"""Mean ratings, intervals over participants and clips and difference tests against numbers worked out by hand."""

import numpy as np
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
    result = analyse(ratings_table(study_type), config())
    sources = result.analysis.sources
    assert list(sources.index) == ["real", "a2m", "gru"]
    assert sources["score"].tolist() == pytest.approx([14 / 3, 3.0, 4 / 3])
    # One clip per source: the clips' variance is unknown, the interval is the t interval
    # (2 degrees of freedom) of the bootstrap variance over participants, cut to the scale.
    real = [5, 4, 5]
    se = np.sqrt(np.var(real) / 3)  # a bootstrap mean's variance: the plain variance / n
    low, high = sources.loc["real", ["ci_low", "ci_high"]].tolist()
    assert high == 5.0
    assert 14 / 3 - low == pytest.approx(scipy_stats.t.ppf(0.975, 2) * se, rel=0.25)
    assert sources["n_judgements"].tolist() == [3, 3, 3]
    assert any("have a single clip" in note for note in result.notes)


def test_sources_compared_by_differences_with_holm():
    result = analyse(ratings_table(), config())
    tests = {t.name: t.frame for t in result.tables}["differences"].set_index(["a", "b"])
    assert "pairwise_tests" not in {t.name for t in result.tables}
    row = tests.loc[("a2m", "gru")]
    assert row["difference"] == pytest.approx(3.0 - 4 / 3)
    # Per participant a2m - gru is 2, 2, 1: the bootstrap variance of its mean is
    # (2/9) / 3, and the test is a t test on 2 degrees of freedom.
    assert row["se"] == pytest.approx(np.sqrt(2 / 27), rel=0.25)
    assert row["df"] == pytest.approx(2.0)
    assert row["p"] == pytest.approx(2 * scipy_stats.t.sf(row["difference"] / row["se"], 2))
    assert tests["p_holm"].tolist() == pytest.approx(holm(tests["p"]).tolist())


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
