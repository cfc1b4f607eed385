"""Krippendorff's alpha: agreement between raters who judged the same units.

Follows Krippendorff (2011), "Computing Krippendorff's Alpha-Reliability": values are
tallied per unit, each unit with ``m >= 2`` values adds its pairs to the coincidence
matrix ``o[c, k]`` with weight ``1 / (m - 1)``, and

    alpha = 1 - (n - 1) * sum(o * delta^2) / sum(n_c n_k delta^2)

with ``n_c`` the pairable values of category ``c`` and ``n`` their total. Units with a
single value are left out. Any number of raters may judge a unit, and a unit may hold
several values of one rater.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy import sparse

from analysis.stats import percentile_interval

LEVELS = ("nominal", "ordinal", "interval")
# Fewest units (stimuli, or pairs of them, judged at least twice) for which a report
# states alpha without a warning. The interval comes from resampling units: with a few
# units the resamples are a handful of distinct sets, so the percentile interval is
# coarse and may even miss the estimate, and one unit moves alpha by tenths. Thirty is
# the usual floor for a bootstrap over independent units, and a study that wants alpha
# should plan for that many (Krippendorff 2011, section E, asks for more still to test a
# minimum alpha).
MIN_AGREEMENT_UNITS = 30


def few_units_text(n_units: int) -> str:
    """Return the warning for agreement measured over fewer than
    :data:`MIN_AGREEMENT_UNITS` units."""
    return (f"agreement rests on only {n_units} {'unit' if n_units == 1 else 'units'} judged "
            f"by two or more participants (a firm figure needs {MIN_AGREEMENT_UNITS} or more): "
            f"with so few units "
            f"the bootstrap interval is coarse and one unit can move alpha by tenths, so read "
            f"alpha as a rough indication only; show each clip (or pair) to more participants "
            f"for a firmer figure")


def krippendorff_alpha(units, values, level: str = "nominal", bootstrap: int = 0,
                       confidence: float = 0.95, seed: int = 0) -> dict:
    """Return Krippendorff's alpha of ``values`` (one per judgement) grouped by ``units``.

    ``level`` picks the difference function: ``nominal`` (any two different values
    disagree alike), ``ordinal`` (by how many values lie between them) or ``interval``
    (squared difference). Missing values are ignored. With ``bootstrap > 0`` the units
    are resampled that many times for a percentile interval.

    Returns ``alpha``, ``ci_low``, ``ci_high``, ``level``, ``n_units`` (units with two or
    more values) and ``n_values`` (their values).
    """
    if level not in LEVELS:
        raise ValueError(f"unknown level {level!r}; choose from {', '.join(LEVELS)}")
    frame = pd.DataFrame({"unit": np.asarray(units), "value": np.asarray(values)}).dropna()
    unit_codes, _ = pd.factorize(frame["unit"])
    value_codes, categories = pd.factorize(frame["value"], sort=True)
    n_units, n_categories = (unit_codes.max() + 1 if len(unit_codes) else 0), len(categories)
    result = {"alpha": float("nan"), "ci_low": float("nan"), "ci_high": float("nan"),
              "level": level, "n_units": 0, "n_values": 0}
    if n_units == 0:
        return result
    counts = sparse.csr_matrix(
        (np.ones(len(unit_codes)), (unit_codes, value_codes)), shape=(n_units, n_categories)
    )
    per_unit = np.asarray(counts.sum(axis=1)).ravel()
    counts = counts[per_unit >= 2]
    per_unit = per_unit[per_unit >= 2]
    result.update(n_units=int(len(per_unit)), n_values=int(per_unit.sum()))
    if len(per_unit) == 0:
        return result

    totals = np.asarray(counts.sum(axis=0)).ravel()
    delta = _squared_differences(level, totals, categories)
    result["alpha"] = _alpha(_coincidences(counts, per_unit), totals, delta)
    if bootstrap > 0:
        samples = _bootstrap(counts, delta, level, categories, bootstrap, seed)
        samples = samples[np.isfinite(samples)]
        if samples.size:
            low, high = percentile_interval(samples, confidence)
            result.update(ci_low=float(low), ci_high=float(high))
    return result


def _coincidences(counts, per_unit) -> np.ndarray:
    """Return the coincidence matrix ``(C, C)`` of pairable units."""
    scaled = sparse.diags(1.0 / (per_unit - 1)) @ counts
    within = np.asarray(scaled.sum(axis=0)).ravel()
    return (counts.T @ scaled).toarray() - np.diag(within)


def _alpha(coincidences, totals, delta) -> float:
    n = totals.sum()
    expected = totals @ delta @ totals
    if n <= 1 or expected == 0:
        return float("nan")  # every value alike: agreement is undefined
    return float(1.0 - (n - 1) * np.sum(coincidences * delta) / expected)


def _squared_differences(level, totals, categories) -> np.ndarray:
    if level == "nominal":
        return 1.0 - np.eye(len(totals))
    if level == "interval":
        numbers = np.asarray(categories, dtype=float)
        return (numbers[:, None] - numbers[None, :]) ** 2
    # Ordinal: the values from c to k, less half of the two ends, squared.
    cumulative = np.concatenate([[0.0], np.cumsum(totals)])
    low = np.minimum.outer(np.arange(len(totals)), np.arange(len(totals)))
    high = np.maximum.outer(np.arange(len(totals)), np.arange(len(totals)))
    between = cumulative[high + 1] - cumulative[low]
    return (between - (totals[:, None] + totals[None, :]) / 2) ** 2


def _bootstrap(counts, delta, level, categories, repeats, seed) -> np.ndarray:
    """Return alpha for ``repeats`` resamples of the pairable units (with replacement).

    Units with the same tally of values contribute alike, so drawing units amounts to
    drawing how many units of each distinct tally a replicate holds: a multinomial over
    tallies, which costs the number of tallies rather than of units.
    """
    rng = np.random.default_rng(seed)
    tallies, members = np.unique(counts.toarray(), axis=0, return_counts=True)
    n_tallies, n_categories = tallies.shape
    sizes = tallies.sum(axis=1)
    # Each tally's own coincidences, flattened: (T, C*C).
    pairs = (tallies[:, :, None] * tallies[:, None, :]
             - tallies[:, :, None] * np.eye(n_categories)[None]) / (sizes - 1)[:, None, None]
    pairs = pairs.reshape(n_tallies, -1)
    weights = rng.multinomial(members.sum(), members / members.sum(), size=repeats).astype(float)
    coincidences = (weights @ pairs).reshape(repeats, n_categories, n_categories)
    totals = weights @ tallies
    samples = np.empty(repeats)
    for r in range(repeats):
        d = delta if level != "ordinal" else _squared_differences(level, totals[r], categories)
        samples[r] = _alpha(coincidences[r], totals[r], d)
    return samples
