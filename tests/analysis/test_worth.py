"""Plackett-Luce and Bradley-Terry fits against maximum-likelihood solutions known exactly.

When the counts of each outcome equal their probabilities under worths w times a total,
the score equations hold at w, so w is the (unique) maximum-likelihood estimate.
"""

import numpy as np
import pytest
from scipy import sparse

from analysis import worth

LOG_421 = np.log([4.0, 2.0, 1.0]) - np.log([4.0, 2.0, 1.0]).mean()
# Rankings of items 0, 1, 2 with worths 4, 2, 1: P(0,1,2) = 4/7 * 2/3 = 40/105, ...
RANKINGS = np.array([[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]])
RANKING_COUNTS = np.array([40, 20, 24, 6, 10, 5])
# Pairs, winner first: 0 beats 1 with 4/6, 0 beats 2 with 4/5, 1 beats 2 with 2/3.
PAIRS = np.array([[0, 1], [1, 0], [0, 2], [2, 0], [1, 2], [2, 1]])
PAIR_COUNTS = np.array([4, 2, 4, 1, 2, 1])


def test_plackett_luce_recovers_the_exact_maximum():
    assert worth.fit(RANKINGS, RANKING_COUNTS, 3, prior=0) == pytest.approx(LOG_421, abs=1e-9)
    probabilities = RANKING_COUNTS / 105
    expected = float(RANKING_COUNTS @ np.log(probabilities))
    assert worth.log_likelihood(RANKINGS, RANKING_COUNTS, np.log([4, 2, 1])) == pytest.approx(expected)


def test_bradley_terry_is_plackett_luce_of_pairs():
    assert worth.fit(PAIRS, PAIR_COUNTS, 3, prior=0) == pytest.approx(LOG_421, abs=1e-9)
    # The same pairs padded into a wider table of orderings.
    padded = np.hstack([PAIRS, -np.ones((6, 1), dtype=int)])
    assert worth.fit(padded, PAIR_COUNTS, 3, prior=0) == pytest.approx(LOG_421, abs=1e-9)


def test_two_items_give_the_log_odds():
    assert worth.fit(np.array([[0, 1], [1, 0]]), np.array([3, 1]), 2, prior=0) == pytest.approx(
        [np.log(3) / 2, -np.log(3) / 2])


def test_prior_keeps_an_unbeaten_item_finite_and_shrinks():
    unbeaten = worth.fit(np.array([[0, 1]]), np.array([5]), 2)
    assert np.all(np.isfinite(unbeaten)) and 0 < unbeaten[0] < 3
    shrunk = worth.fit(PAIRS, PAIR_COUNTS, 3)
    assert np.ptp(shrunk) < np.ptp(LOG_421)
    assert np.argsort(shrunk).tolist() == [2, 1, 0]


def test_matches_choix_on_partial_rankings():
    choix = pytest.importorskip("choix")
    rng = np.random.default_rng(0)
    orders = np.argsort(-(np.array([1.0, 0.5, 0.0, -0.5, -1.0]) + rng.gumbel(size=(80, 5))), axis=1)
    orders[:30, 3:] = -1
    expected = choix.ilsr_rankings(5, [list(o[o >= 0]) for o in orders], alpha=0)
    assert worth.fit(orders, np.ones(80), 5, prior=0) == pytest.approx(expected - expected.mean(), abs=1e-6)


def test_bootstrap_replicates_are_exact_refits_and_intervals_cover_the_fit():
    rng = np.random.default_rng(3)
    orders = np.argsort(-(np.array([1.0, 0.0, -1.0]) + rng.gumbel(size=(300, 3))), axis=1)
    participants = rng.integers(0, 30, 300)
    data = worth.rankings(orders, participants, 3)
    resampled = worth.resample_participants(30, 50, seed=4)
    result = worth.bootstrap(data, 50, resampled=resampled)
    assert result["theta"] == pytest.approx(worth.fit(orders, np.ones(300), 3))
    weights = np.asarray((sparse.csr_matrix(resampled[7:8].astype(float)) @ data.counts).todense())[0]
    assert result["samples"][7] == pytest.approx(worth.fit(data.orders, weights, 3), abs=1e-7)
    assert np.all(result["ci_low"] < result["theta"]) and np.all(result["theta"] < result["ci_high"])
    assert resampled.sum(axis=1) == pytest.approx(np.full(50, 30))


def test_bootstrap_without_participants_to_resample_has_no_interval():
    data = worth.rankings(RANKINGS, np.zeros(6, dtype=int), 3)
    result = worth.bootstrap(data, 20)
    assert np.all(np.isnan(result["ci_low"])) and result["samples"].shape == (0, 3)
