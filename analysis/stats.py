"""Intervals, tests and corrections used by every study type, vectorised over groups.

Each function works on counts or arrays, so that it can be checked against numbers
computed by hand; the one exception is :func:`participant_bootstrap`, which resamples a
table's participants with all their judgements and is how every study type gives its
intervals (judgements of one participant are alike, so they are not independent).
"""

from __future__ import annotations

import itertools
import warnings

import numpy as np
import pandas as pd
from scipy import stats


def z_value(confidence: float = 0.95) -> float:
    """Return the two-sided normal quantile of ``confidence`` (1.96 for 95 %)."""
    return float(stats.norm.ppf(0.5 + confidence / 2))


def wilson_interval(successes, n, confidence: float = 0.95):
    """Return the Wilson score interval ``(low, high)`` of ``successes`` out of ``n``.

    Arrays broadcast; ``n = 0`` gives NaN.
    """
    successes = np.asarray(successes, dtype=float)
    n = np.asarray(n, dtype=float)
    z = z_value(confidence)
    with np.errstate(invalid="ignore", divide="ignore"):
        share = successes / n
        centre = (share + z * z / (2 * n)) / (1 + z * z / n)
        half = z * np.sqrt(share * (1 - share) / n + z * z / (4 * n * n)) / (1 + z * z / n)
        # It holds the share (exactly 0 at no successes, 1 at all; rounding aside).
        return np.minimum(centre - half, share), np.maximum(centre + half, share)


def t_interval(mean, sd, n, confidence: float = 0.95):
    """Return the Student-t interval ``mean -/+ t(n-1) sd / sqrt(n)``; NaN when ``n < 2``."""
    mean, sd, n = (np.asarray(v, dtype=float) for v in (mean, sd, n))
    with np.errstate(invalid="ignore", divide="ignore"):
        half = stats.t.ppf(0.5 + confidence / 2, np.where(n >= 2, n - 1, np.nan)) * sd / np.sqrt(n)
    return mean - half, mean + half


# Below this many participants an interval over participants rests on too few of them
# to mean much; analyses add a note saying so.
MIN_PARTICIPANTS = 10


def participant_draws(n_participants: int, repeats: int, seed: int = 0) -> np.ndarray:
    """Return ``(repeats, n_participants)`` participant codes drawn with replacement.

    The draws are those of ``analysis.worth.resample_participants`` with the same
    ``seed`` (which counts them), so worths and other intervals resample alike.
    """
    return np.concatenate([chunk for _, chunk in _draws(n_participants, repeats, seed)]
                          or [np.empty((0, n_participants), dtype=np.int64)])


def _draws(n_participants: int, repeats: int, seed: int, per_chunk: int | None = None):
    """Yield ``(first replicate, (r, P) participant codes)`` in chunks of bounded size."""
    rng = np.random.default_rng(seed)
    per_chunk = per_chunk or max(1, CHUNK_ELEMENTS // max(n_participants, 1))
    for first in range(0, repeats, per_chunk):
        size = min(per_chunk, repeats - first)
        chunk = np.empty((size, n_participants), dtype=np.int64)
        for r in range(size):
            chunk[r] = rng.integers(0, n_participants, n_participants, dtype=np.int32)
        yield first, chunk


# Largest (replicates x participants) array the bootstraps hold at once.
CHUNK_ELEMENTS = 4_000_000


def participant_bootstrap(rows: pd.DataFrame, statistic, n: int = 1000, seed: int = 0,
                          confidence: float = 0.95, participant: str = "pcode"):
    """Return ``(estimate, ci_low, ci_high)`` of ``statistic(rows)``, with percentile
    intervals over participants.

    Each of the ``n`` replicates draws as many participants as ``rows`` has, with
    replacement, keeps every row of each participant drawn, and computes
    ``statistic`` of that table. A participant drawn twice enters twice, as two
    participants: the ``participant`` column of a replicate is renumbered ``0..P-1`` by
    draw, so a statistic may group by it.

    ``statistic`` takes a table like ``rows`` and returns a number, a 1-D array or a
    ``pd.Series`` (aligned on the index of the full data's result; a group missing from a
    replicate is NaN there). Replicates where a value is NaN are left out of that value's
    interval. The three results have the statistic's shape (Series keep its index).
    Intervals are NaN when ``n`` is 0 or ``rows`` has fewer than 2 participants.

        mean = lambda t: t.groupby("source")["rating"].mean()
        score, low, high = participant_bootstrap(rows, mean, n=1000, seed=0)

    This copies the table per replicate; for means and shares (ratios of sums over
    participants) :func:`ratio_bootstrap` gives the same intervals from per-participant
    sums, fast enough for a million judgements (:func:`bootstrap_means` wraps it).
    """
    estimate = statistic(rows)
    codes, people = pd.factorize(rows[participant])
    n_participants = len(people)
    as_series = isinstance(estimate, pd.Series)
    flat = np.atleast_1d(np.asarray(estimate, dtype=float))
    nan = np.full(flat.shape, np.nan)
    if n <= 0 or n_participants < 2:
        return _shaped(estimate, flat, nan, nan)
    order = np.argsort(codes, kind="stable")
    sizes = np.bincount(codes, minlength=n_participants)
    starts = np.r_[0, np.cumsum(sizes)[:-1]]
    samples = np.full((n, flat.size), np.nan)
    for first, chunk in _draws(n_participants, n, seed):
        for r, drawn in enumerate(chunk, start=first):
            lengths = sizes[drawn]
            offsets = np.arange(lengths.sum()) - np.repeat(np.cumsum(lengths) - lengths, lengths)
            replicate = rows.take(order[np.repeat(starts[drawn], lengths) + offsets])
            replicate[participant] = np.repeat(np.arange(n_participants), lengths)
            value = statistic(replicate)
            if as_series:
                value = pd.Series(value).reindex(estimate.index)
            samples[r] = np.asarray(value, dtype=float).ravel()
    low, high = _percentiles(samples, confidence)
    return _shaped(estimate, flat, low, high)


def per_participant(participants, groups, n_groups: int, values=None,
                    n_participants: int | None = None) -> np.ndarray:
    """Return ``(P, n_groups)`` sums of ``values`` (default: counts) per participant code
    ``0..P-1`` and group code ``0..n_groups-1``: the input of :func:`ratio_bootstrap`."""
    participants = np.asarray(participants, dtype=np.int64)
    groups = np.asarray(groups, dtype=np.int64)
    if n_participants is None:
        n_participants = int(participants.max()) + 1 if len(participants) else 0
    sums = np.bincount(participants * n_groups + groups, weights=values,
                       minlength=n_participants * n_groups)
    return sums.reshape(n_participants, n_groups).astype(float)


def ratio_bootstrap(numerator, denominator, n: int = 1000, seed: int = 0,
                    confidence: float = 0.95):
    """Return ``(estimate, ci_low, ci_high)`` of ratios of sums over participants, each
    ``(G,)``, with percentile intervals from resampling participants.

    ``numerator`` and ``denominator`` are ``(P, G)`` per-participant sums (see
    :func:`per_participant`): a share is (successes, trials), a mean (sum, count). The
    estimate is ``numerator.sum(0) / denominator.sum(0)``; a replicate weighs each
    participant by how often it was drawn. The draws are :func:`participant_draws`'s,
    so this equals :func:`participant_bootstrap` of the same ratio. Replicates where a
    ratio is undefined (0 / 0) are left out of its interval; intervals are NaN when ``n`` is
    0 or there are fewer than 2 participants.
    """
    numerator = np.asarray(numerator, dtype=float)
    denominator = np.asarray(denominator, dtype=float)
    n_participants, n_groups = numerator.shape
    with np.errstate(invalid="ignore", divide="ignore"):
        estimate = numerator.sum(axis=0) / denominator.sum(axis=0)
    nan = np.full(n_groups, np.nan)
    if n <= 0 or n_participants < 2:
        return estimate, nan, nan
    samples = np.empty((n, n_groups))
    for first, chunk in _draws(n_participants, n, seed):
        weights = np.stack([np.bincount(drawn, minlength=n_participants) for drawn in chunk])
        weights = weights.astype(float)
        with np.errstate(invalid="ignore", divide="ignore"):
            samples[first:first + len(chunk)] = (weights @ numerator) / (weights @ denominator)
    low, high = _percentiles(samples, confidence)
    return estimate, low, high


def bootstrap_means(rows: pd.DataFrame, value: str, by=("source",), n: int = 1000,
                    seed: int = 0, confidence: float = 0.95,
                    participant: str = "pcode") -> pd.DataFrame:
    """Return the mean of column ``value`` per group of ``by`` columns, with intervals over
    participants (:func:`ratio_bootstrap`; the same as :func:`participant_bootstrap` of
    the group means).

    Returns ``score``, ``ci_low``, ``ci_high`` indexed by the groups (sorted). A share is
    the mean of a 0/1 column.
    """
    by = list(by)
    groups = rows.groupby(by, observed=True, sort=True).size().index
    keys = pd.MultiIndex.from_frame(rows[by]) if len(by) > 1 else pd.Index(rows[by[0]])
    codes = groups.get_indexer(keys)
    people = pd.factorize(rows[participant])[0]
    sums = per_participant(people, codes, len(groups), rows[value].to_numpy(dtype=float))
    counts = per_participant(people, codes, len(groups))
    score, low, high = ratio_bootstrap(sums, counts, n, seed, confidence)
    return pd.DataFrame({"score": score, "ci_low": low, "ci_high": high}, index=groups)


def _percentiles(samples, confidence):
    tail = 100 * (1 - confidence) / 2
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a value NaN in every replicate
        low, high = np.nanpercentile(samples, [tail, 100 - tail], axis=0)
    return low, high


def _shaped(estimate, flat, low, high):
    if isinstance(estimate, pd.Series):
        return (estimate, pd.Series(low, index=estimate.index), pd.Series(high, index=estimate.index))
    if np.ndim(estimate) == 0:
        return float(flat[0]), float(low[0]), float(high[0])
    return flat, low, high


def small_sample_note(n_participants: int) -> str | None:
    """Return a note for a report when ``n_participants`` is below :data:`MIN_PARTICIPANTS`."""
    if n_participants >= MIN_PARTICIPANTS:
        return None
    return (f"only {n_participants} participant(s): intervals over participants rest on fewer "
            f"than {MIN_PARTICIPANTS} people and mean little; read them as rough")


def percentile_interval(samples: np.ndarray, confidence: float = 0.95, axis: int = 0):
    """Return the percentile interval of bootstrap ``samples`` along ``axis``."""
    tail = 100 * (1 - confidence) / 2
    low, high = np.percentile(samples, [tail, 100 - tail], axis=axis)
    return low, high


def holm(pvalues) -> np.ndarray:
    """Return Holm's step-down adjusted p-values; NaN entries stay NaN and are not counted."""
    p = np.asarray(pvalues, dtype=float)
    adjusted = np.full_like(p, np.nan)
    valid = np.flatnonzero(np.isfinite(p))
    if valid.size == 0:
        return adjusted
    order = valid[np.argsort(p[valid], kind="stable")]
    m = order.size
    steps = (m - np.arange(m)) * p[order]
    adjusted[order] = np.minimum(np.maximum.accumulate(steps), 1.0)
    return adjusted


def binomial_p(successes: int, n: int, p: float) -> float:
    """Return the two-sided exact binomial test p-value of ``successes`` in ``n`` against ``p``."""
    if n == 0 or not np.isfinite(p):
        return float("nan")
    return float(stats.binomtest(int(successes), int(n), float(p)).pvalue)


def dprime(hits, n_signal, false_alarms, n_noise) -> np.ndarray:
    """Return d' = z(H) - z(F) with the log-linear correction (Hautus, 1995).

    ``H = (hits + 0.5) / (n_signal + 1)`` and ``F = (false_alarms + 0.5) / (n_noise + 1)``,
    so rates of 0 or 1 stay finite. Arrays broadcast.
    """
    hits, n_signal, false_alarms, n_noise = (
        np.asarray(v, dtype=float) for v in (hits, n_signal, false_alarms, n_noise)
    )
    hit_rate = (hits + 0.5) / (n_signal + 1)
    false_rate = (false_alarms + 0.5) / (n_noise + 1)
    return stats.norm.ppf(hit_rate) - stats.norm.ppf(false_rate)


def friedman(scores: np.ndarray) -> dict:
    """Return Friedman's test and Kendall's W for ``scores`` ``(blocks, treatments)``.

    Scores are ranked within each block (ties get average ranks; the statistic is
    corrected for them). Lower or higher scores rank alike: only the order matters.
    Returns ``statistic`` (chi-squared), ``df``, ``p``, ``kendall_w``, ``n_blocks``,
    ``mean_ranks`` ``(treatments,)``.
    """
    scores = np.asarray(scores, dtype=float)
    n, k = scores.shape
    if n < 2 or k < 2:
        raise ValueError(f"Friedman's test needs at least 2 blocks and 2 treatments; got {n} x {k}")
    ranks = stats.rankdata(scores, axis=1)
    rank_sums = ranks.sum(axis=0)
    # Each value in a tie group of size t adds t^2 - 1, so a group adds t^3 - t.
    group_sizes = (scores[:, :, None] == scores[:, None, :]).sum(axis=2)
    ties = float(np.sum(group_sizes.astype(float) ** 2 - 1))
    denominator = n * k * (k + 1) / 12 - ties / (12 * (k - 1))
    spread = np.sum((rank_sums - n * (k + 1) / 2) ** 2)
    if denominator <= 0:
        statistic, w = float("nan"), float("nan")
    else:
        statistic = float(spread / denominator)
        w = statistic / (n * (k - 1))
    p = float(stats.chi2.sf(statistic, k - 1)) if np.isfinite(statistic) else float("nan")
    return {
        "statistic": statistic, "df": k - 1, "p": p, "kendall_w": w, "n_blocks": n,
        "mean_ranks": rank_sums / n,
    }


def pairwise_wilcoxon(scores: np.ndarray, names) -> pd.DataFrame:
    """Return Wilcoxon signed-rank tests between every pair of columns of ``scores``.

    ``scores`` is ``(blocks, treatments)``, paired by block. Columns: ``a``, ``b``,
    ``n`` (blocks where they differ), ``median_difference`` (a - b), ``statistic``, ``p``,
    ``p_holm`` (over all pairs).
    """
    rows = []
    for (i, a), (j, b) in itertools.combinations(enumerate(names), 2):
        difference = scores[:, i] - scores[:, j]
        nonzero = int(np.count_nonzero(difference))
        if nonzero == 0:
            statistic, p = float("nan"), 1.0
        else:
            result = stats.wilcoxon(scores[:, i], scores[:, j], zero_method="wilcox")
            statistic, p = float(result.statistic), float(result.pvalue)
        rows.append({"a": a, "b": b, "n": nonzero, "median_difference": float(np.median(difference)),
                     "statistic": statistic, "p": p})
    table = pd.DataFrame(rows, columns=["a", "b", "n", "median_difference", "statistic", "p"])
    table["p_holm"] = holm(table["p"])
    return table


def pairwise_mann_whitney(values: np.ndarray, groups: np.ndarray, names) -> pd.DataFrame:
    """Return two-sided Mann-Whitney U tests between every pair of groups.

    Columns: ``a``, ``b``, ``n_a``, ``n_b``, ``u`` (of ``a``), ``superiority`` (the
    probability that a value of ``a`` beats one of ``b``, ties counting half: U / (n_a n_b)),
    ``p``, ``p_holm`` (over all pairs).
    """
    by_group = {name: values[groups == name] for name in names}
    rows = []
    for a, b in itertools.combinations(names, 2):
        x, y = by_group[a], by_group[b]
        if len(x) == 0 or len(y) == 0:
            u, p = float("nan"), float("nan")
        else:
            result = stats.mannwhitneyu(x, y, alternative="two-sided")
            u, p = float(result.statistic), float(result.pvalue)
        rows.append({"a": a, "b": b, "n_a": len(x), "n_b": len(y), "u": u,
                     "superiority": u / (len(x) * len(y)) if len(x) and len(y) else float("nan"),
                     "p": p})
    table = pd.DataFrame(rows, columns=["a", "b", "n_a", "n_b", "u", "superiority", "p"])
    table["p_holm"] = holm(table["p"])
    return table


def kruskal_wallis(values: np.ndarray, groups: np.ndarray, names) -> dict:
    """Return the Kruskal-Wallis H test across ``names``: ``statistic``, ``df``, ``p``."""
    samples = [values[groups == name] for name in names]
    samples = [s for s in samples if len(s)]
    if len(samples) < 2 or np.ptp(np.concatenate(samples)) == 0:
        return {"statistic": float("nan"), "df": len(samples) - 1, "p": float("nan")}
    result = stats.kruskal(*samples)
    return {"statistic": float(result.statistic), "df": len(samples) - 1, "p": float(result.pvalue)}


def one_sample_t(values: np.ndarray, confidence: float = 0.95) -> dict:
    """Return the mean of ``values``, its t interval, and the t test against 0."""
    values = np.asarray(values, dtype=float)
    n = len(values)
    mean = float(values.mean()) if n else float("nan")
    sd = float(values.std(ddof=1)) if n > 1 else float("nan")
    low, high = t_interval(mean, sd, n, confidence)
    if n > 1 and sd > 0:
        result = stats.ttest_1samp(values, 0.0)
        t, p = float(result.statistic), float(result.pvalue)
    else:
        t, p = float("nan"), float("nan")
    return {"mean": mean, "ci_low": float(low), "ci_high": float(high), "sd": sd, "n": n,
            "t": t, "p": p}
