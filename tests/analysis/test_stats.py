"""Intervals, tests and corrections against numbers worked out by hand."""

import numpy as np
import pytest
from scipy import stats as scipy_stats

from analysis import stats


def test_wilson_interval_of_8_in_10():
    # centre (0.8 + z^2/20) / (1 + z^2/10), half-width z sqrt(0.016 + z^2/400) / (1 + z^2/10)
    low, high = stats.wilson_interval(8, 10)
    assert (low, high) == pytest.approx((0.49016, 0.94332), abs=1e-5)


def test_wilson_interval_stays_inside_0_1_and_is_nan_without_data():
    low, high = stats.wilson_interval(np.array([0, 5, 0]), np.array([5, 5, 0]))
    assert low[0] == pytest.approx(0.0) and high[1] == pytest.approx(1.0)
    assert 0 < high[0] < 0.5 and 0.5 < low[1] < 1
    assert np.isnan(low[2]) and np.isnan(high[2])


def test_t_interval_of_one_to_five():
    # mean 3, sd sqrt(2.5), t(4) = 2.7764: 3 -/+ 2.7764 * 1.5811 / sqrt(5)
    low, high = stats.t_interval(3.0, np.std([1, 2, 3, 4, 5], ddof=1), 5)
    assert (low, high) == pytest.approx((1.03676, 4.96324), abs=1e-5)
    assert np.isnan(stats.t_interval(3.0, 0.0, 1)[0])


def test_holm_steps_down_and_keeps_order():
    # sorted 0.01, 0.03, 0.04 -> 3 x 0.01, 2 x 0.03, max(0.06, 1 x 0.04)
    assert stats.holm([0.01, 0.04, 0.03]) == pytest.approx([0.03, 0.06, 0.06])
    adjusted = stats.holm([0.5, np.nan, 0.6])
    assert adjusted[0] == pytest.approx(1.0) and np.isnan(adjusted[1]) and adjusted[2] == pytest.approx(1.0)


def test_dprime_with_the_log_linear_correction():
    # H = 9.5 / 11, F = 2.5 / 11
    assert stats.dprime(9, 10, 2, 10) == pytest.approx(1.84466, abs=1e-5)
    perfect = stats.dprime(10, 10, 0, 10)
    assert np.isfinite(perfect) and perfect == pytest.approx(2 * scipy_stats.norm.ppf(10.5 / 11))
    assert stats.dprime(5, 10, 5, 10) == pytest.approx(0.0)


def test_friedman_and_kendalls_w_without_ties():
    # Three raters rank three objects: (1,2,3), (1,3,2), (2,1,3). Rank sums 4, 6, 8;
    # S = 8, W = 12 S / (n^2 (k^3 - k)) = 96 / 216, chi2 = n (k - 1) W.
    result = stats.friedman(np.array([[1, 2, 3], [1, 3, 2], [2, 1, 3]]))
    assert result["kendall_w"] == pytest.approx(96 / 216)
    assert result["statistic"] == pytest.approx(3 * 2 * 96 / 216)
    assert result["p"] == pytest.approx(scipy_stats.chi2.sf(8 / 3, 2))
    assert result["mean_ranks"] == pytest.approx([4 / 3, 2, 8 / 3])


def test_friedman_corrects_for_ties():
    # Mean ranks of three participants (rows) for three sources: ties within rows.
    # Rank sums 4.5, 6, 7.5 -> spread 4.5; ties 6 + 6 + 24 = 36;
    # chi2 = 4.5 / (3*3*4/12 - 36/24) = 3, W = 3 / (3 * 2) = 0.5.
    scores = np.array([[1.5, 1.5, 3.0], [1.0, 2.5, 2.5], [2.0, 2.0, 2.0]])
    result = stats.friedman(scores)
    assert result["statistic"] == pytest.approx(3.0)
    assert result["kendall_w"] == pytest.approx(0.5)
    assert result["p"] == pytest.approx(np.exp(-1.5))  # chi2 with 2 df
    assert result["statistic"] == pytest.approx(scipy_stats.friedmanchisquare(*scores.T).statistic)


def test_friedman_needs_two_blocks():
    with pytest.raises(ValueError, match="at least 2 blocks"):
        stats.friedman(np.array([[1, 2, 3]]))


def test_pairwise_tests_match_scipy_and_are_holm_corrected():
    rng = np.random.default_rng(0)
    scores = rng.normal(size=(30, 3)) + [0.0, 0.5, 1.0]
    table = stats.pairwise_wilcoxon(scores, ["a", "b", "c"])
    assert table[["a", "b"]].values.tolist() == [["a", "b"], ["a", "c"], ["b", "c"]]
    assert table.loc[0, "p"] == pytest.approx(scipy_stats.wilcoxon(scores[:, 0], scores[:, 1]).pvalue)
    assert table["p_holm"].tolist() == pytest.approx(stats.holm(table["p"]).tolist())

    values = np.array([5, 4, 4, 5, 2, 3, 1, 2])
    groups = np.array(["real"] * 4 + ["gen"] * 4)
    mw = stats.pairwise_mann_whitney(values, groups, ["gen", "real"])
    expected = scipy_stats.mannwhitneyu(values[4:], values[:4], alternative="two-sided")
    assert mw.loc[0, "u"] == expected.statistic == 0.0
    assert mw.loc[0, "superiority"] == 0.0 and mw.loc[0, "p"] == pytest.approx(expected.pvalue)
