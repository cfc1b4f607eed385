"""Plackett-Luce worth of sources from rankings, and Bradley-Terry as its two-item case.

A ranking of ``m`` items is read as ``m - 1`` choices: the best of all, then the best of
the rest, ... each item chosen with probability ``exp(theta_i) / sum(exp(theta))`` over
the items still in play. A pairwise choice is a ranking of two.

The likelihood only depends on how often each *choice* (a set of items in play and the
one chosen) was made, and there are few distinct choices (186 for complete rankings of 6
sources) however many trials there are. Fits therefore work on choice counts, and a
bootstrap over participants only changes the counts: participants x orderings counts,
times resampling weights, times orderings x choices. Newton's method on the concave
log-likelihood is batched over bootstrap replicates; its gradient and Hessian are a few
matrix products over choices.

``prior`` adds, per item, that many virtual wins and as many virtual losses against a
reference of log-worth 0, which keeps the worth finite when an item never (or always)
wins and vanishes beside real data; ``prior=0`` is the plain maximum likelihood.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.special import expit

from analysis.stats import percentile_interval

PRIOR = 1.0
# Largest (replicates x choices) or (replicates x participants) array held at once.
CHUNK_ELEMENTS = 8_000_000


@dataclass
class Rankings:
    """Distinct orderings and how often each participant gave each.

    ``orders`` ``(U, m)`` item indices best first, padded with ``-1``; ``counts`` sparse
    ``(P, U)``; ``n_items`` the number of items.
    """

    orders: np.ndarray
    counts: sparse.csr_matrix
    n_items: int

    @property
    def totals(self) -> np.ndarray:
        return np.asarray(self.counts.sum(axis=0)).ravel()


def rankings(orders, participants, n_items: int, n_participants: int | None = None) -> Rankings:
    """Return the :class:`Rankings` of ``orders`` ``(T, m)`` given by ``participants`` ``(T,)``.

    ``participants`` are codes ``0..P-1`` (``P = n_participants`` when given, so that
    subsets of a study share the participants' numbering).
    """
    orders = np.asarray(orders, dtype=np.int64)
    unique, inverse = _unique_rows(orders, n_items)
    participants = np.asarray(participants, dtype=np.int64)
    if n_participants is None:
        n_participants = int(participants.max()) + 1 if len(participants) else 0
    counts = sparse.csr_matrix((np.ones(len(orders)), (participants, inverse)),
                               shape=(n_participants, len(unique)))
    return Rankings(unique, counts, n_items)


def fit(orders, weights, n_items: int, prior: float = PRIOR, iterations: int = 100,
        tolerance: float = 1e-10) -> np.ndarray:
    """Return log-worths ``(n_items,)`` centred on 0 for ``orders`` ``(U, m)`` given
    ``weights`` ``(U,)`` times each."""
    choices = _Choices(np.asarray(orders, dtype=np.int64), n_items)
    counts = np.asarray(weights, dtype=float)[None] @ choices.incidence
    theta = _newton(choices, np.asarray(counts), np.zeros((1, n_items)), prior, iterations, tolerance)
    return theta[0] - theta[0].mean()


def choice_counts(orders, n_items: int):
    """Return the distinct choices of ``orders`` ``(N, m)`` and the sparse ``(N, E)`` counts
    of each choice per ordering (a weighted sum of their rows is what :func:`refit` takes)."""
    choices = _Choices(np.asarray(orders, dtype=np.int64), n_items)
    return choices, choices.incidence


def refit(choices, counts, prior: float = PRIOR, start=None, iterations: int = 100,
          tolerance: float = 1e-8) -> np.ndarray:
    """Return centred log-worths ``(B, K)`` for choice counts ``(B, E)`` of ``choices``
    (from :func:`choice_counts`), all fitted at once from ``start`` ``(K,)``."""
    counts = np.atleast_2d(np.asarray(counts, dtype=float))
    theta = np.zeros((len(counts), choices.n_items)) if start is None else np.tile(start, (len(counts), 1))
    theta = _newton(choices, counts, theta, prior, iterations, tolerance)
    return theta - theta.mean(axis=1, keepdims=True)


def log_likelihood(orders, weights, theta) -> float:
    """Return the Plackett-Luce log-likelihood of ``theta`` ``(K,)`` (no prior)."""
    theta = np.asarray(theta, dtype=float)
    choices = _Choices(np.asarray(orders, dtype=np.int64), len(theta))
    counts = np.asarray(np.asarray(weights, dtype=float)[None] @ choices.incidence)[0]
    shift = theta.max()
    log_norm = np.log(choices.sets @ np.exp(theta - shift)) + shift
    return float(counts @ (theta[choices.chosen] - log_norm))


def resample_participants(n_participants: int, repeats: int, seed: int = 0) -> np.ndarray:
    """Return ``(repeats, P)`` counts: how often each participant is drawn per replicate."""
    rng = np.random.default_rng(seed)
    counts = np.empty((repeats, n_participants), dtype=np.float32)
    for r in range(repeats):
        draws = rng.integers(0, n_participants, n_participants, dtype=np.int32)
        counts[r] = np.bincount(draws, minlength=n_participants)
    return counts


def bootstrap(data: Rankings, repeats: int, seed: int = 0, prior: float = PRIOR,
              confidence: float = 0.95, resampled: np.ndarray | None = None,
              iterations: int = 100, tolerance: float = 1e-8) -> dict:
    """Return the fit on all data and percentile intervals from resampled participants.

    Each replicate redraws the participants with replacement (``resampled``, from
    :func:`resample_participants`, or drawn here from ``seed``) and refits.

    Returns ``theta`` ``(K,)``, ``ci_low``, ``ci_high`` ``(K,)`` (NaN without repeats or
    with fewer than 2 participants) and ``samples`` ``(repeats, K)``.
    """
    n_items = data.n_items
    choices = _Choices(data.orders, n_items)
    totals = np.asarray(data.totals[None] @ choices.incidence)
    theta = _newton(choices, totals, np.zeros((1, n_items)), prior, iterations, tolerance)[0]
    n_participants = data.counts.shape[0]
    nan = np.full(n_items, np.nan)
    active = np.flatnonzero(np.asarray(data.counts.sum(axis=1)).ravel())
    if repeats <= 0 or len(active) < 2:
        return {"theta": theta - theta.mean(), "ci_low": nan, "ci_high": nan,
                "samples": np.empty((0, n_items))}
    if resampled is None:
        resampled = resample_participants(n_participants, repeats, seed)
    repeats = len(resampled)
    by_participant = (data.counts @ choices.incidence).tocsr()  # (P, E)
    n_choices = by_participant.shape[1]
    if by_participant.nnz > 0.1 * n_participants * n_choices:
        # Dense enough for BLAS; counts stay whole numbers well inside float32's range.
        by_participant = by_participant.toarray().astype(np.float32)
    samples = np.empty((repeats, n_items))
    per_chunk = max(1, CHUNK_ELEMENTS // max(n_participants, n_choices, 1))
    for first in range(0, repeats, per_chunk):
        weights = np.asarray(resampled[first:first + per_chunk], dtype=np.float32)
        if sparse.issparse(by_participant):
            counts = np.asarray((by_participant.T @ weights.T).T, dtype=float)
        else:
            counts = (weights @ by_participant).astype(float)
        start = np.tile(theta, (len(weights), 1))
        samples[first:first + per_chunk] = _newton(choices, counts, start, prior, iterations, tolerance)
    samples -= samples.mean(axis=1, keepdims=True)
    low, high = percentile_interval(samples, confidence)
    return {"theta": theta - theta.mean(), "ci_low": low, "ci_high": high, "samples": samples}


class _Choices:
    """The distinct choices in a set of orderings.

    ``sets`` ``(E, K)``: how many of each item were in play; ``chosen`` ``(E,)``;
    ``incidence`` sparse ``(U, E)``: how often ordering ``u`` makes choice ``e``.
    """

    def __init__(self, orders, n_items):
        n_orders, m = orders.shape
        lengths = (orders >= 0).sum(axis=1)
        stage_order, stage = np.nonzero(np.arange(m)[None, :] < (lengths - 1)[:, None])
        # The items in play at stage t are those at places t..m-1; sort them to name the set.
        in_play = np.where(np.arange(m)[None, :] >= stage[:, None], orders[stage_order], -1)
        in_play = np.sort(in_play, axis=1)
        chosen = orders[stage_order, stage]
        keyed = np.concatenate([in_play, chosen[:, None]], axis=1)
        unique, inverse = _unique_rows(keyed, n_items)
        self.chosen = unique[:, -1]
        self.sets = np.zeros((len(unique), n_items))
        members = unique[:, :-1]
        rows, cols = np.nonzero(members >= 0)
        np.add.at(self.sets, (rows, members[rows, cols]), 1.0)
        self.incidence = sparse.csr_matrix(
            (np.ones(len(inverse)), (stage_order, inverse)), shape=(n_orders, len(unique)))
        self.chosen_one_hot = np.zeros((len(unique), n_items))
        self.chosen_one_hot[np.arange(len(unique)), self.chosen] = 1.0
        # Products of set counts, for the Hessian: (E, K*K).
        self.pairs = (self.sets[:, :, None] * self.sets[:, None, :]).reshape(len(unique), -1)
        self.n_items = n_items

    def derivatives(self, counts, theta):
        """Return the gradient ``(B, K)`` and Hessian ``(B, K, K)`` for choice counts ``(B, E)``."""
        batch, n_items = theta.shape
        worth = np.exp(theta - theta.max(axis=1, keepdims=True))
        totals = worth @ self.sets.T  # (B, E): the worth in play at each choice
        per_total = counts / totals
        expected = worth * (per_total @ self.sets)
        gradient = counts @ self.chosen_one_hot - expected
        products = (per_total / totals) @ self.pairs
        hessian = (worth[:, :, None] * worth[:, None, :]) * products.reshape(batch, n_items, n_items)
        idx = np.arange(n_items)
        hessian[:, idx, idx] -= expected
        return gradient, hessian


def _newton(choices, counts, theta, prior, iterations, tolerance) -> np.ndarray:
    """Return ``theta`` ``(B, K)`` moved to the maxima for choice counts ``(B, E)``."""
    theta = theta.copy()
    n_items = theta.shape[1]
    eye = np.eye(n_items)
    for _ in range(iterations):
        gradient, hessian = choices.derivatives(counts, theta)
        if prior > 0:
            p = expit(theta)
            gradient += prior * (1 - 2 * p)
            hessian -= eye * (2 * prior * p * (1 - p))[:, :, None]
        else:
            # The data leave a common shift free: pin the mean instead.
            gradient -= theta.sum(axis=1, keepdims=True)
            hessian -= 1.0
        # The tiny ridge keeps saturated fits (an item that always wins) solvable.
        step = np.linalg.solve(1e-9 * eye - hessian, gradient[:, :, None])[:, :, 0]
        largest = np.abs(step).max(axis=1, keepdims=True)
        # Far from the optimum a full Newton step can overshoot: cap its length.
        theta += step * np.minimum(1.0, 2.0 / np.maximum(largest, 1e-300))
        if largest.max() < tolerance:
            break
    return theta


def _unique_rows(rows: np.ndarray, n_items: int):
    """Return the distinct rows of an integer array with values ``-1..n_items`` and the
    inverse index."""
    base = n_items + 2
    if rows.shape[1] * np.log2(base) < 62:
        # One integer per row (digits in base n_items + 2) sorts far faster than rows.
        keys = (rows + 1) @ base ** np.arange(rows.shape[1], dtype=np.int64)
        _, first, inverse = np.unique(keys, return_index=True, return_inverse=True)
        return rows[first], inverse.ravel()
    unique, inverse = np.unique(rows, axis=0, return_inverse=True)
    return unique, inverse.ravel()
