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


def batch_counts(post: Posterior, contrasts, weights, size: int, focus: float = 0.0,
                 pairs=None) -> np.ndarray:
    """Return how many of the next ``size`` comparisons each pair gets ``(M,)`` when they
    are planned together (as ASAP batches its comparisons): one at a time, each the pair
    whose comparison most lowers ``sum_c weight_c var_c^(1 + focus)`` over the target
    contrasts, the posterior covariance updated by its expected information before the
    next (Sherman-Morrison), so that a batch spreads over the pairs that each lower a
    different variance, as a spanning tree of comparisons does, and leans on the widest."""
    pairs = all_pairs(post.n_sources) if pairs is None else np.asarray(pairs)
    contrasts = np.atleast_2d(np.asarray(contrasts, dtype=float))
    weights = np.asarray(weights, dtype=float)
    d = np.zeros((len(pairs), post.n_sources))
    d[np.arange(len(pairs)), pairs[:, 0]] = 1.0
    d[np.arange(len(pairs)), pairs[:, 1]] = -1.0
    mu = d @ post.mean
    cov = post.cov.copy()
    counts = np.zeros(len(pairs))
    power = 1.0 + focus
    for _ in range(size):
        sd_ = d @ cov  # (M, K)
        var_d = np.einsum("mk,mk->m", sd_, d)
        kappa = 1.0 / np.sqrt(1.0 + np.pi * var_d / 8.0)
        p = expit(kappa * mu)
        w = kappa * p * (1 - p)
        var_c = np.einsum("ck,kl,cl->c", contrasts, cov, contrasts)
        drop = w[:, None] * (sd_ @ contrasts.T) ** 2 / (1.0 + w * var_d)[:, None]  # (M, C)
        # Exact change of the objective for each candidate pair.
        after = np.maximum(var_c[None, :] - drop, 1e-300)
        gain = (weights * (var_c ** power)).sum() - (after ** power) @ weights
        best = int(np.argmax(gain))
        counts[best] += 1
        u = sd_[best]
        cov -= w[best] * np.outer(u, u) / (1.0 + w[best] * var_d[best])
    return counts


def distribution(post: Posterior, target="order", floor: float = FLOOR, sharpness: float = 1.0,
                 focus: float = 0.0, seed: int = 0, batch: int = 0) -> dict:
    """Return the sampling distribution over pairs: ``{"pairs": [[i, j], ...], "p": [...]}``
    (JSON-ready), ``floor`` of it uniform and the rest proportional to the pairs' scores
    raised to ``sharpness``. ``focus`` > 0 weighs each target contrast also by its
    variance relative to the largest, to that power (aiming at the widest interval, which
    a stopping rule on the widest interval waits for). ``batch`` > 0: the rest is instead
    the share of each pair in a batch of that many comparisons planned together
    (:func:`batch_counts`; ``sharpness`` unused)."""
    if not 0 < floor <= 1:
        raise ValueError("floor must be in (0, 1]: every pair keeps a chance")
    pairs = all_pairs(post.n_sources)
    contrasts, weights = target_contrasts(post, target, seed=seed)
    if batch:
        counts = batch_counts(post, contrasts, weights, batch, focus, pairs)
        uniform = np.full(len(pairs), 1.0 / len(pairs))
        p = floor * uniform + (1 - floor) * counts / counts.sum()
        return {"pairs": pairs.tolist(), "p": (p / p.sum()).tolist()}
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
    return _plan(dist["pairs"], dist["p"], _pick_pair, n_trials, clips, shown, rng, min_showings,
                 seen, group_of, counterbalance)


def _plan(members, weights, pick, n_trials, clips, shown, rng, min_showings, seen, group_of,
          seat) -> list[tuple]:
    """The loop of :func:`plan_pairs` and :func:`plan_sets`: ``n_trials`` draws of sources
    by weight (those with a clip short of ``min_showings`` first), each turned into clips
    by ``pick``, then seated by ``seat``."""
    usable = [(tuple(m), float(w)) for m, w in zip(members, weights)
              if all(clips.get(s) for s in m)]
    seen = {frozenset(trial) for trial in seen}
    chosen = []
    for _ in range(n_trials):
        short = {s for s, ids in clips.items() if any(shown[c] < min_showings for c in ids)}
        candidates = [(m, w) for m, w in usable if short & set(m)] if short else []
        trial = (_draw(candidates, pick, clips, shown, seen, rng, group_of) if candidates
                 else None) or _draw(usable, pick, clips, shown, seen, rng, group_of)
        if trial is None:
            break
        seen.add(frozenset(trial))
        for clip in trial:
            shown[clip] += 1
        chosen.append(trial)
    owner = {clip: source for source, ids in clips.items() for clip in ids}
    return seat(chosen, rng, owner.__getitem__)


def _draw(candidates, pick, clips, shown, seen, rng, group_of=None):
    """Draw sources by weight until ``pick`` finds them clips (None when none is left)."""
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
        members, _ = candidates.pop(index)
        trial = pick(members, clips, shown, seen, rng, group_of)
        if trial is not None:
            return trial
    return None


def _by_use(ids, shown, rng):
    return sorted(ids, key=lambda clip: (shown[clip], rng.random()))


def _pick_pair(members, clips, shown, seen, rng, group_of):
    """The least-shown unseen pair of clips of a pair of sources (one condition)."""
    a, b = members
    # The least-shown clip of either source first, then its least-shown partner.
    first, second = (a, b) if rng.random() < 0.5 else (b, a)
    partners = _by_use(clips[second], shown, rng)
    for x in _by_use(clips[first], shown, rng):
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


# --- Sets of sources: best of k and ranking (Plackett-Luce) ---------------------------

MAX_SETS = 2000
SET_DRAWS = 64


def choice_posterior(n_sources: int, chosen, among, weight=None, prior_sd: float = PRIOR_SD,
                     iterations: int = 50) -> Posterior:
    """Return the :class:`Posterior` of Luce choices: ``chosen[e]`` (a source index) was
    chosen among the sources ``among[e]`` (a sequence of indices that holds it; a source
    listed twice was shown twice), ``weight`` times each. A ranking of ``m`` clips is its
    ``m - 1`` successive choices (Plackett-Luce); a best-of-k answer is one. Two sources
    compared are a choice among two, so :func:`posterior` is the special case of pairs."""
    chosen = np.asarray(chosen, dtype=np.int64)
    weight = np.ones(len(chosen)) if weight is None else np.asarray(weight, dtype=float)
    shown = np.zeros((len(chosen), n_sources))
    for row, members in enumerate(among):
        np.add.at(shown[row], np.asarray(list(members), dtype=np.int64), 1.0)
    # Distinct (set, choice) counts: the fit then costs their number, however many answers.
    keyed = np.concatenate([shown, chosen[:, None].astype(float)], axis=1) if len(chosen) \
        else np.zeros((0, n_sources + 1))
    unique, inverse = np.unique(keyed, axis=0, return_inverse=True)
    counts = np.zeros(len(unique))
    np.add.at(counts, inverse.ravel(), weight)
    sets, picked = unique[:, :-1], unique[:, -1].astype(np.int64)
    wins = np.bincount(picked, weights=counts, minlength=n_sources)
    precision_prior = 1.0 / prior_sd ** 2
    theta = np.zeros(n_sources)

    def derivatives(theta):
        e = sets * np.exp(theta - theta.max())[None, :]
        p = e / e.sum(axis=1, keepdims=True)  # (E, K) chance of each source at each choice
        gradient = wins - counts @ p - precision_prior * theta
        hessian = -(np.diag(counts @ p) - (p * counts[:, None]).T @ p)
        return gradient, hessian - precision_prior * np.eye(n_sources)

    for _ in range(iterations):
        gradient, hessian = derivatives(theta)
        step = np.linalg.solve(-hessian, gradient)
        step *= min(1.0, 2.0 / max(np.abs(step).max(), 1e-300))
        theta += step
        if np.abs(step).max() < 1e-9:
            break
    _, hessian = derivatives(theta)
    cov = np.linalg.inv(-hessian)
    centre = np.eye(n_sources) - 1.0 / n_sources
    return Posterior(theta - theta.mean(), centre @ cov @ centre, int(round(weight.sum())))


def all_sets(n_sources: int, size: int, limit: int = MAX_SETS, seed: int = 0) -> np.ndarray:
    """Return the candidate sets of ``size`` distinct sources ``(M, size)``, sorted: every
    one, or ``limit`` drawn at random (each source in some) when there are more."""
    size = min(size, n_sources)
    from math import comb

    if comb(n_sources, size) <= limit:
        return np.array(list(itertools.combinations(range(n_sources), size)),
                        dtype=np.int64).reshape(-1, size)
    rng = np.random.default_rng(seed)
    drawn = {tuple(sorted(rng.choice(n_sources, size, replace=False).tolist())) for _ in range(limit)}
    return np.array(sorted(drawn), dtype=np.int64)


def set_information(post: Posterior, sets, depth: int | None = 1, draws: int = SET_DRAWS,
                    seed: int = 0) -> np.ndarray:
    """Return the expected Fisher information ``(M, k, k)`` of one answer on each set of
    sources (in the set's own coordinates), averaged over the posterior: ``depth`` Luce
    choices per answer (1: best of k; None: the whole ranking, ``k - 1`` choices), each
    among the sources not yet chosen, in orders drawn as Plackett-Luce draws."""
    sets = np.asarray(sets, dtype=np.int64)
    m, k = sets.shape
    depth = k - 1 if depth is None else min(depth, k - 1)
    rng = np.random.default_rng(seed)
    theta = rng.multivariate_normal(post.mean, post.cov, size=draws, method="eigh")  # (D, K)
    local = theta[:, sets]  # (D, M, k)
    utility = local + rng.gumbel(size=local.shape)
    order = np.argsort(-utility, axis=2)
    remaining = np.ones(local.shape, dtype=bool)
    info = np.zeros((m, k, k))
    for stage in range(depth):
        e = np.where(remaining, np.exp(local - local.max(axis=2, keepdims=True)), 0.0)
        p = e / e.sum(axis=2, keepdims=True)  # (D, M, k)
        stage_info = (np.einsum("dmi,ij->dmij", p, np.eye(k)) - p[..., :, None] * p[..., None, :])
        info += stage_info.mean(axis=0)
        np.put_along_axis(remaining, order[:, :, stage:stage + 1], False, axis=2)
    return info


def set_scores(post: Posterior, contrasts, weights, sets, depth: int | None = 1,
               seed: int = 0) -> np.ndarray:
    """Return, per set ``(M,)``, the expected weighted drop in the contrasts' variances from
    one more answer on that set: with the set's information ``I = B B^T`` (embedded in
    every source), the covariance ``S`` loses ``S B (1 + B^T S B)^-1 B^T S`` (Woodbury;
    for a pair this is :func:`pair_scores`' Sherman-Morrison step)."""
    sets = np.asarray(sets, dtype=np.int64)
    contrasts = np.atleast_2d(np.asarray(contrasts, dtype=float))
    weights = np.asarray(weights, dtype=float)
    info = set_information(post, sets, depth, seed=seed)
    sc = contrasts @ post.cov  # (C, K): c^T S
    scores = np.empty(len(sets))
    for row, (members, inf) in enumerate(zip(sets, info)):
        values, vectors = np.linalg.eigh(inf)
        keep = values > 1e-12
        b = vectors[:, keep] * np.sqrt(values[keep])  # (k, r): I = b b^T on the set
        sb = post.cov[:, members] @ b  # (K, r)
        inner = np.eye(b.shape[1]) + b.T @ post.cov[np.ix_(members, members)] @ b
        csb = sc[:, members] @ b  # (C, r)
        drop = np.einsum("cr,rs,cs->c", csb, np.linalg.inv(inner), csb)
        scores[row] = drop @ weights
        del sb
    return scores


def set_distribution(post: Posterior, size: int, target="order", depth: int | None = 1,
                     floor: float = FLOOR, sharpness: float = 1.0, focus: float = 0.0,
                     seed: int = 0) -> dict:
    """Return the sampling distribution over sets of ``size`` sources: ``{"sets": [[...],
    ...], "p": [...], "size": size}`` (JSON-ready), as :func:`distribution` does for pairs:
    ``floor`` of it uniform over the candidate sets, the rest proportional to
    :func:`set_scores` raised to ``sharpness`` (``focus`` as there)."""
    if not 0 < floor <= 1:
        raise ValueError("floor must be in (0, 1]: every set keeps a chance")
    sets = all_sets(post.n_sources, size, seed=seed)
    contrasts, weights = target_contrasts(post, target, seed=seed)
    if focus:
        variance = post.sd(contrasts) ** 2
        weights = weights * (variance / variance.max()) ** focus
    scores = np.maximum(set_scores(post, contrasts, weights, sets, depth, seed=seed), 0.0) ** sharpness
    uniform = np.full(len(sets), 1.0 / len(sets))
    p = uniform if scores.sum() <= 0 else floor * uniform + (1 - floor) * scores / scores.sum()
    return {"sets": sets.tolist(), "p": (p / p.sum()).tolist(), "size": int(sets.shape[1])}


def balanced_sets(n_sources: int, size: int, seed: int = 0) -> dict:
    """Return the uniform distribution over sets of ``size`` sources."""
    sets = all_sets(n_sources, size, seed=seed)
    return {"sets": sets.tolist(), "p": [1.0 / len(sets)] * len(sets), "size": int(sets.shape[1])}


def plan_sets(dist: dict, n_trials: int, clips: dict, shown: Counter, rng, min_showings: int = 0,
              seen=(), group_of=None) -> list[tuple]:
    """Return ``n_trials`` trials (tuples of clips, in their seats) for one participant.

    As :func:`plan_pairs` for sets: ``dist`` from :func:`set_distribution`; while any clip
    has fewer than ``min_showings`` showings, sets with its source are drawn first; within
    a source the least-shown clip of the trial's condition is taken; no participant sees
    the same clips together twice; and the seats are counterbalanced per participant
    (:func:`seat_sets`: each source's clips spread over the positions)."""
    return _plan(dist["sets"], dist["p"], _pick_set, n_trials, clips, shown, rng, min_showings,
                 seen, group_of, seat_sets)


def _pick_set(members, clips, shown, seen, rng, group_of):
    """The least-shown unseen clips of a set of sources, all of one condition."""
    # The least-shown clip of a source of the set decides the condition; each other
    # source then gives its least-shown clip of that condition.
    lead = rng.choice(members)
    for first in _by_use(clips[lead], shown, rng):
        group = None if group_of is None else group_of(first)
        trial = [first]
        for source in members:
            if source == lead:
                continue
            fits = [c for c in _by_use(clips[source], shown, rng)
                    if group is None or group_of(c) == group]
            if not fits:
                break
            trial.append(fits[0])
        if len(trial) == len(members) and frozenset(trial) not in seen:
            return tuple(trial)
    return None


def seat_sets(trials: list[tuple], rng, source_of) -> list[tuple]:
    """Return ``trials`` (tuples of clips) with their clips seated so that within the list
    each source is as evenly spread over the positions as can be: trial by trial, the
    assignment of clips to seats that least repeats a source's earlier seats (random
    among equals). Pairs are seated by :func:`counterbalance` instead (exact)."""
    from scipy.optimize import linear_sum_assignment

    if trials and all(len(t) == 2 for t in trials):
        return counterbalance(trials, rng, source_of)
    used: Counter = Counter()
    seated = []
    for trial in trials:
        k = len(trial)
        cost = np.array([[used[(source_of(clip), seat)] + 0.01 * rng.random() for seat in range(k)]
                         for clip in trial])
        rows, cols = linear_sum_assignment(cost)
        seats = [None] * k
        for r, c in zip(rows, cols):
            seats[c] = trial[r]
            used[(source_of(trial[r]), c)] += 1
        seated.append(tuple(seats))
    return seated


# --- Stopping rules -------------------------------------------------------------------

STOP_RULES = ("interval_width", "rank_certainty", "judgements")


@dataclass
class Spread:
    """Variances of the differences between sources ``(K, K)``: ``model`` (the posterior's,
    judgements alone), ``sandwich`` (clustered by participant and by clip), ``steady`` (the
    model's plus one clip variance pooled over every pair of sources, times how much each
    source leans on single clips) and the degrees of freedom of a t interval (None: normal)."""

    model: np.ndarray
    sandwich: np.ndarray | None = None
    steady: np.ndarray | None = None
    df: int | None = None

    @property
    def stopping(self) -> np.ndarray:
        """The variance a stopping rule reads: the steady one where clips are known (it
        barely moves with the luck of the answers, so stopping on it does not pick looks
        where an interval happens to be narrow), else the model's."""
        return self.model if self.steady is None else self.steady


def difference_variance(cov) -> np.ndarray:
    d = np.diag(cov)
    return np.maximum(d[:, None] + d[None, :] - 2 * cov, 1e-12)


def spread(post: Posterior, winner, loser, clip_w=None, clip_l=None, who=None) -> Spread:
    """Return the :class:`Spread` of a Bradley-Terry posterior of comparisons ``winner``
    beat ``loser``; with each comparison's clips ``clip_w``, ``clip_l`` and participant
    ``who`` (any labels), also the sandwich variance clustered by participant and by clip
    (a comparison belongs to both its clips; CR1 factors) and the steady one."""
    model = difference_variance(post.cov)
    if clip_w is None or len(winner) == 0:
        return Spread(model)
    winner, loser = np.asarray(winner, dtype=np.int64), np.asarray(loser, dtype=np.int64)
    theta = post.mean
    p = expit(theta[winner] - theta[loser])
    rows = np.arange(len(winner))
    g = np.zeros((len(winner), post.n_sources))
    g[rows, winner] = 1 - p
    g[rows, loser] = -(1 - p)
    return _clustered(post, g, np.concatenate([rows, rows]),
                      np.concatenate([np.asarray(clip_w), np.asarray(clip_l)]),
                      np.concatenate([winner, loser]), who)


def choice_spread(post: Posterior, chosen, among, among_clips=None, who=None,
                  weight=None) -> Spread:
    """Return the :class:`Spread` of a Plackett-Luce posterior of Luce choices
    (:func:`choice_posterior`: ``chosen[e]`` among the sources ``among[e]``); with the
    clips shown at each choice ``among_clips[e]`` (aligned with ``among[e]``) and its
    participant ``who[e]`` (any labels), also the sandwich variance clustered by
    participant and by clip and the steady one, as :func:`spread` for pairs. Each choice
    gives the score ``1 - p`` to its chosen source and ``-p`` to every other one shown
    (``p`` the softmax of the posterior mean over the set); it belongs to every clip shown
    at it (a ranking's later choices to the clips still unranked there)."""
    model = difference_variance(post.cov)
    if among_clips is None or len(chosen) == 0:
        return Spread(model)
    k = post.n_sources
    chosen = np.asarray(chosen, dtype=np.int64)
    sizes = [len(members) for members in among]
    events = np.repeat(np.arange(len(chosen)), sizes)
    members = np.concatenate([np.asarray(list(m), dtype=np.int64) for m in among])
    clips = np.concatenate([np.asarray(list(c), dtype=object) for c in among_clips])
    if len(clips) != len(members):
        raise ValueError("among_clips must name one clip per source of each choice")
    shown = np.zeros((len(chosen), k))
    np.add.at(shown, (events, members), 1.0)
    e = shown * np.exp(post.mean - post.mean.max())[None, :]
    g = -e / e.sum(axis=1, keepdims=True)
    g[np.arange(len(chosen)), chosen] += 1.0
    if weight is not None:
        g *= np.asarray(weight, dtype=float)[:, None]
    return _clustered(post, g, events, clips, members, who)


def _clustered(post: Posterior, g, events, clip_labels, clip_sources, who) -> Spread:
    """The clustered part of :func:`spread` and :func:`choice_spread`: ``g`` ``(E, K)`` the
    score of each event (a comparison or a choice) at the posterior mean; each event
    ``events[i]`` showed the clip ``clip_labels[i]`` of the source ``clip_sources[i]``;
    ``who`` ``(E,)`` each event's participant. The sandwich clusters by participant and by
    clip (an event belongs to every clip it showed; CR1 factors); the steady variance is
    the model's plus one clip variance pooled over every pair of sources, times each
    source's lean on single clips (the sum of squared shares of its clips' showings)."""
    model = difference_variance(post.cov)
    k = post.n_sources
    clips, codes = np.unique(np.asarray(clip_labels).astype(str), return_inverse=True)
    codes = codes.ravel()
    who = np.unique(np.asarray(who).astype(str), return_inverse=True)[1].ravel()
    n_clips, n_people = len(clips), int(who.max()) + 1
    scores = g[events]

    def meat(key, n_keys, values):
        sums = np.zeros((n_keys, k))
        np.add.at(sums, key, values)
        return sums.T @ sums

    clips_part = meat(codes, n_clips, scores)
    both = meat(who[events] * n_clips + codes, n_people * n_clips, scores)
    middle = (meat(who, n_people, g) * n_people / max(n_people - 1, 1)
              + (clips_part - both) * n_clips / max(n_clips - 1, 1))
    sandwich = difference_variance(post.cov @ middle @ post.cov)
    source_of = np.zeros(n_clips, dtype=np.int64)
    source_of[codes] = clip_sources
    showings = np.bincount(codes, minlength=n_clips).astype(float)
    per_source = np.bincount(source_of, weights=showings, minlength=k)
    lean = np.bincount(source_of, weights=showings ** 2, minlength=k) / np.maximum(per_source, 1) ** 2
    factor = lean[:, None] + lean[None, :]
    upper = np.triu_indices(k, 1)
    tau2 = max(0.0, (sandwich - model)[upper].sum() / max(factor[upper].sum(), 1e-300))
    clips_per_source = np.bincount(source_of, minlength=k)
    df = max(1, min(n_people - 1, 2 * int(clips_per_source[clips_per_source > 0].min()) - 2))
    return Spread(model, sandwich, model + tau2 * factor, df)


def stop_pairs(post: Posterior, target="order") -> list[tuple[int, int]]:
    """Return the differences a stopping rule looks at, as pairs of sources (the better
    estimated first): the top two, every neighbour in the estimated order, or the pairs
    of given contrasts (rows with one +1 and one -1, e.g. :func:`versus`)."""
    order = [int(i) for i in np.argsort(-post.mean)]
    if isinstance(target, str):
        if target == "top_two":
            return [(order[0], order[1])]
        return list(zip(order[:-1], order[1:]))
    pairs = []
    for row in np.atleast_2d(np.asarray(target, dtype=float)):
        a, b = int(np.argmax(row)), int(np.argmin(row))
        pairs.append((a, b) if post.mean[a] >= post.mean[b] else (b, a))
    return pairs


def stop_state(post: Posterior, rule: dict, target="order", judgements: int = 0,
               variance: Spread | None = None, confidence: float = 0.95, draws: int = 4000,
               seed: int = 0) -> dict:
    """Return where a study stands against its stopping rule (JSON-ready): ``width`` (the
    widest ``confidence`` interval of the target's differences), ``certainty`` (the
    posterior probability that the target's estimated order is right: every one of its
    differences has the estimated sign), ``judgements``, and ``met``: the first of
    ``rule``'s settings (:data:`STOP_RULES`) that holds, or ""."""
    from scipy import stats

    variance = variance or Spread(difference_variance(post.cov))
    pairs = stop_pairs(post, target)
    var = variance.stopping
    level = 0.5 + confidence / 2
    t = stats.norm.ppf(level) if variance.df is None else stats.t.ppf(level, variance.df)
    width = max(2 * t * float(np.sqrt(var[a, b])) for a, b in pairs)
    # The posterior, widened where the stopping variance is wider than the model's.
    inflate = max(float(var[a, b] / variance.model[a, b]) for a, b in pairs)
    rng = np.random.default_rng(seed)
    sample = rng.multivariate_normal(post.mean, post.cov * max(inflate, 1.0), size=draws,
                                     method="eigh")
    right = np.ones(draws, dtype=bool)
    for a, b in pairs:
        right &= sample[:, a] > sample[:, b]
    certainty = float(right.mean())
    met = ""
    for name in STOP_RULES:
        if name not in rule:
            continue
        value = rule[name]
        if ((name == "interval_width" and width <= value)
                or (name == "rank_certainty" and certainty >= value)
                or (name == "judgements" and judgements >= value)):
            met = name
            break
    return {"width": round(width, 4), "certainty": round(certainty, 4), "judgements": int(judgements),
            "met": met, "pairs": [list(pair) for pair in pairs],
            "interval": "model" if variance.steady is None else "clips"}
