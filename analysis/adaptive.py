"""Adaptive choice of the next pairs of sources to compare (plain Python, no Django).

From the comparisons so far (winner and loser sources) a Bradley-Terry posterior is fitted:
the maximum a posteriori log-worths under a weak normal prior and the Laplace covariance
around them (:func:`posterior`). Each candidate pair of sources ``(i, j)`` is scored by how
much one more comparison of it is expected to shrink the variance of the contrasts the
study is about (:func:`pair_scores`): the order of the sources (every pair that may stand
next to each other in the order), the top two, or given contrasts such as "mine against
each baseline". One comparison adds ``w d d^T`` to the posterior precision (``d = e_i -
e_j``, ``w`` the expected ``p (1 - p)``), so by Sherman-Morrison a contrast ``c`` loses
``w (c^T S d)^2 / (1 + w d^T S d)`` of its variance.

The design stays randomised: :func:`distribution` turns the scores into probabilities over
pairs and mixes them with a floor of uniform (balanced) sampling, so every pair keeps a
chance and the analysis can treat the pairs shown as drawn by a known, data-dependent
rule (the likelihood does not depend on it). :func:`plan_pairs` draws one participant's
trials from such a distribution under the constraints that keep the inference valid:

- clips are random too: within a source the least-shown clip comes first, and while any
  clip has fewer than ``min_showings`` showings, pairs with its source are drawn first;
- no participant sees the same two clips twice (repeat trials are added by the caller);
- positions are counterbalanced per participant: the session's pairs are seated along an
  Euler circuit of their multigraph (:func:`counterbalance`), so each source is on the
  left and on the right equally often, or at most once more on one side.

The distribution is recomputed in the background every ``k`` answers, never per request.
"""

from __future__ import annotations

import itertools
from collections import Counter
from dataclasses import dataclass

import numpy as np
from scipy.special import expit

PRIOR_SD = 3.0
FLOOR = 0.2
DRAWS = 400


@dataclass
class Posterior:
    """Laplace approximation of the Bradley-Terry posterior: ``mean`` ``(K,)`` (centred
    log-worths) and ``cov`` ``(K, K)`` (of the centred log-worths)."""

    mean: np.ndarray
    cov: np.ndarray
    n: int

    @property
    def n_sources(self) -> int:
        return len(self.mean)

    def sd(self, contrasts) -> np.ndarray:
        """Return the posterior standard deviation of each row of ``contrasts`` ``(C, K)``."""
        c = np.atleast_2d(contrasts)
        return np.sqrt(np.einsum("ck,kl,cl->c", c, self.cov, c))


def posterior(n_sources: int, winner, loser, weight=None, prior_sd: float = PRIOR_SD,
              iterations: int = 50) -> Posterior:
    """Return the :class:`Posterior` of comparisons ``winner`` beat ``loser`` (source indices,
    ``weight`` times each; ties can be given as half a win each way)."""
    winner = np.asarray(winner, dtype=np.int64)
    loser = np.asarray(loser, dtype=np.int64)
    weight = np.ones(len(winner)) if weight is None else np.asarray(weight, dtype=float)
    # Distinct (winner, loser) counts: the fit then costs K^2, however many comparisons.
    counts = np.zeros((n_sources, n_sources))
    np.add.at(counts, (winner, loser), weight)
    precision_prior = 1.0 / prior_sd ** 2
    theta = np.zeros(n_sources)
    for _ in range(iterations):
        gradient, hessian = _derivatives(counts, theta, precision_prior)
        step = np.linalg.solve(-hessian, gradient)
        step *= min(1.0, 2.0 / max(np.abs(step).max(), 1e-300))
        theta += step
        if np.abs(step).max() < 1e-9:
            break
    _, hessian = _derivatives(counts, theta, precision_prior)
    cov = np.linalg.inv(-hessian)
    centre = np.eye(n_sources) - 1.0 / n_sources
    return Posterior(theta - theta.mean(), centre @ cov @ centre, int(round(weight.sum())))


def _derivatives(counts, theta, precision_prior):
    diff = theta[:, None] - theta[None, :]
    p = expit(diff)  # p[i, j]: i beats j
    games = counts + counts.T
    # d/d theta_i of sum_ij counts[i, j] log p[i, j]
    gradient = (counts * (1 - p)).sum(axis=1) - (counts.T * (1 - p.T)).sum(axis=1)
    gradient -= precision_prior * theta
    w = games * p * (1 - p)
    hessian = w.copy()
    hessian[np.diag_indices_from(hessian)] = -(w.sum(axis=1) - np.diag(w))
    hessian -= precision_prior * np.eye(len(theta))
    return gradient, hessian


def all_pairs(n_sources: int) -> np.ndarray:
    """Return every unordered pair of sources ``(M, 2)``, ``i < j``."""
    return np.array(list(itertools.combinations(range(n_sources), 2)), dtype=np.int64).reshape(-1, 2)


def target_contrasts(post: Posterior, target="order", draws: int = DRAWS, seed: int = 0):
    """Return the contrasts ``(C, K)`` a design aims at and their weights ``(C,)``.

    ``target`` is ``"order"`` (each pair of sources weighted by the posterior probability
    that they stand next to each other in the order), ``"top_two"`` (each pair weighted by
    the probability that it is the top two) or an array of given contrasts (rows, weight 1
    each; :func:`versus` makes "one source against each other").
    """
    k = post.n_sources
    if not isinstance(target, str):
        contrasts = np.atleast_2d(np.asarray(target, dtype=float))
        return contrasts, np.ones(len(contrasts))
    if target not in ("order", "top_two"):
        raise ValueError(f"target: {target!r} is not 'order', 'top_two' or an array of contrasts")
    rng = np.random.default_rng(seed)
    sample = rng.multivariate_normal(post.mean, post.cov, size=draws, method="eigh")
    ranked = np.argsort(-sample, axis=1)
    first, second = ranked[:, :-1], ranked[:, 1:]
    if target == "top_two":
        first, second = first[:, :1], second[:, :1]
    low, high = np.minimum(first, second).ravel(), np.maximum(first, second).ravel()
    often = Counter(zip(low.tolist(), high.tolist()))
    contrasts = np.zeros((len(often), k))
    weights = np.empty(len(often))
    for row, ((a, b), n) in enumerate(sorted(often.items())):
        contrasts[row, a], contrasts[row, b] = 1.0, -1.0
        weights[row] = n / draws
    return contrasts, weights


def versus(n_sources: int, source: int, others=None) -> np.ndarray:
    """Return the contrasts ``source - other`` for each of ``others`` (default: all others)."""
    others = [o for o in range(n_sources) if o != source] if others is None else list(others)
    contrasts = np.zeros((len(others), n_sources))
    contrasts[:, source] = 1.0
    contrasts[np.arange(len(others)), others] = -1.0
    return contrasts


def pair_scores(post: Posterior, contrasts, weights, pairs=None) -> np.ndarray:
    """Return, per pair ``(M,)``, the expected weighted drop in the contrasts' variances
    from one more comparison of that pair."""
    pairs = all_pairs(post.n_sources) if pairs is None else np.asarray(pairs)
    d = np.zeros((len(pairs), post.n_sources))
    d[np.arange(len(pairs)), pairs[:, 0]] = 1.0
    d[np.arange(len(pairs)), pairs[:, 1]] = -1.0
    sd_ = d @ post.cov  # (M, K)
    var_d = np.einsum("mk,mk->m", sd_, d)
    mu = d @ post.mean
    # E[p (1 - p)] over the posterior of the difference (probit approximation).
    kappa = 1.0 / np.sqrt(1.0 + np.pi * var_d / 8.0)
    p = expit(kappa * mu)
    w = kappa * p * (1 - p)
    covs = sd_ @ np.atleast_2d(contrasts).T  # (M, C): c^T S d
    drop = w[:, None] * covs ** 2 / (1.0 + w * var_d)[:, None]
    return drop @ np.asarray(weights, dtype=float)


def distribution(post: Posterior, target="order", floor: float = FLOOR, sharpness: float = 1.0,
                 focus: float = 0.0, seed: int = 0) -> dict:
    """Return the sampling distribution over pairs: ``{"pairs": [[i, j], ...], "p": [...]}``
    (JSON-ready), ``floor`` of it uniform and the rest proportional to the pairs' scores
    raised to ``sharpness``. ``focus`` > 0 weighs each target contrast also by its
    variance relative to the largest, to that power (aiming at the widest interval, which
    a stopping rule on the widest interval waits for)."""
    if not 0 < floor <= 1:
        raise ValueError("floor must be in (0, 1]: every pair keeps a chance")
    pairs = all_pairs(post.n_sources)
    contrasts, weights = target_contrasts(post, target, seed=seed)
    if focus:
        variance = post.sd(contrasts) ** 2
        weights = weights * (variance / variance.max()) ** focus
    scores = np.maximum(pair_scores(post, contrasts, weights, pairs), 0.0) ** sharpness
    uniform = np.full(len(pairs), 1.0 / len(pairs))
    p = uniform if scores.sum() <= 0 else floor * uniform + (1 - floor) * scores / scores.sum()
    return {"pairs": pairs.tolist(), "p": (p / p.sum()).tolist()}


def balanced(n_sources: int) -> dict:
    """Return the uniform distribution over pairs (the fallback without a posterior)."""
    pairs = all_pairs(n_sources)
    return {"pairs": pairs.tolist(), "p": [1.0 / len(pairs)] * len(pairs)}


def plan_pairs(dist: dict, n_trials: int, clips: dict, shown: Counter, rng,
               min_showings: int = 0, seen=(), group_of=None) -> list[tuple]:
    """Return ``n_trials`` trials ``(left_clip, right_clip)`` for one participant.

    ``dist`` from :func:`distribution` (pairs of source indices); ``clips`` ``{source:
    [clip ids]}``; ``shown`` counts showings per clip so far (updated in place); ``rng``
    a ``random.Random``; ``seen`` pairs of clips this participant has already judged;
    ``group_of`` maps a clip to its condition (the two clips of a trial share one; default:
    all clips one condition). Sources missing from ``clips`` are never drawn. Fewer trials are returned only when
    no unseen pair of clips is left.
    """
    pairs = [tuple(pair) for pair in dist["pairs"]]
    weights = [float(p) for p in dist["p"]]
    usable = [(pair, w) for pair, w in zip(pairs, weights)
              if clips.get(pair[0]) and clips.get(pair[1])]
    seen = {frozenset(pair) for pair in seen}
    chosen = []
    for _ in range(n_trials):
        short = {s for s, ids in clips.items() if any(shown[c] < min_showings for c in ids)}
        candidates = [(pair, w) for pair, w in usable if short & set(pair)] if short else []
        trial = (_draw(candidates, clips, shown, seen, rng, group_of) if candidates else None) \
            or _draw(usable, clips, shown, seen, rng, group_of)
        if trial is None:
            break
        seen.add(frozenset(trial))
        for clip in trial:
            shown[clip] += 1
        chosen.append(trial)
    owner = {clip: source for source, ids in clips.items() for clip in ids}
    return counterbalance(chosen, rng, owner.__getitem__)


def _draw(candidates, clips, shown, seen, rng, group_of=None):
    """Draw a pair of sources by weight and its least-shown unseen pair of clips."""
    candidates = list(candidates)
    while candidates:
        total = sum(w for _, w in candidates)
        if total <= 0:
            index = rng.randrange(len(candidates))
        else:
            x, index = rng.random() * total, 0
            while index < len(candidates) - 1 and x >= candidates[index][1]:
                x -= candidates[index][1]
                index += 1
        (a, b), _ = candidates.pop(index)

        def by_use(ids):
            return sorted(ids, key=lambda clip: (shown[clip], rng.random()))

        # The least-shown clip of either source first, then its least-shown partner.
        first, second = (a, b) if rng.random() < 0.5 else (b, a)
        partners = by_use(clips[second])
        for x in by_use(clips[first]):
            for y in partners:
                if frozenset((x, y)) not in seen and (group_of is None or group_of(x) == group_of(y)):
                    return (x, y) if first == a else (y, x)
    return None


def counterbalance(trials: list[tuple], rng, source_of=None) -> list[tuple]:
    """Return ``trials`` (pairs of clips) seated left/right so that within the list each
    source is on the left as often as on the right, or at most once more on one side.

    The pairs' sources form a multigraph; its odd-degree vertices are joined to one extra
    vertex so that every vertex has even degree, and each edge is seated along an Euler
    circuit (tail left, head right), so at every source as many edges arrive as leave.
    ``source_of`` maps a clip to its source (default: the clip's ``source`` attribute, or
    for tuples ``(source, clip)`` their first element).
    """
    if source_of is None:
        def source_of(clip):
            return getattr(clip, "source", clip[0] if isinstance(clip, tuple) else clip)
    extra = object()
    edges = [(source_of(a), source_of(b)) for a, b in trials]
    adjacency: dict = {}
    for index, (u, v) in enumerate(edges):
        adjacency.setdefault(u, []).append((v, index))
        adjacency.setdefault(v, []).append((u, index))
    dummy = len(edges)
    for vertex in [v for v, out in adjacency.items() if len(out) % 2]:
        adjacency[vertex].append((extra, dummy))
        adjacency.setdefault(extra, []).append((vertex, dummy))
        dummy += 1
    for out in adjacency.values():
        rng.shuffle(out)
    used = [False] * dummy
    forward = [True] * len(edges)
    for start in list(adjacency):
        # Hierholzer's walk from each vertex with unused edges; orient edges as walked.
        stack = [start]
        while stack:
            vertex = stack[-1]
            out = adjacency[vertex]
            while out and used[out[-1][1]]:
                out.pop()
            if not out:
                stack.pop()
                continue
            other, index = out.pop()
            used[index] = True
            if index < len(edges):
                forward[index] = edges[index][0] == vertex if edges[index][0] != edges[index][1] \
                    else rng.random() < 0.5
            stack.append(other)
    return [(a, b) if keep else (b, a) for (a, b), keep in zip(trials, forward)]
