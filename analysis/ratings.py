"""Realism ratings 1-5: the mean score per source (seed 003, Table 3; seed 004, Table 5).

Means come with percentile intervals from a bootstrap over participants (each
participant's ratings stay together); sources are compared by their rating
distributions (Kruskal-Wallis across all, Mann-Whitney U between each pair with Holm's
correction), which respects that the scale is ordinal.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from analysis import simulate, stats
from analysis.counts import ranked_sources, source_counts
from analysis.formatting import number, p_text, participant_bootstrap_text
from analysis.registry import Analysis, Plot, StudyAnalysis, Table, register_analysis
from analysis.tables import AnalysisError

SCALE = (1, 5)


@register_analysis("rating_standards")
class RatingStandards(StudyAnalysis):
    """Each clip is rated 1-5 after scoring standards with example clips (seed 003)."""

    answer = "rating"
    agreement_level = "ordinal"
    design = ("each clip was rated from 1 to 5 (higher = more realistic) after participants saw "
              "five scoring standards, each a description and an example clip")

    def simulated_trials(self, rng, n_trials, n_sources, clips_per_trial):
        return simulate.every_source(n_trials, n_sources)

    def simulated_answers(self, raters):
        """Quality + rater bias + logistic noise, cut into 1..5 at thresholds spread evenly
        over the strengths."""
        rng, n_rows, strength = raters.rng, raters.n_rows, raters.strength
        latent = (raters.quality + rng.normal(0.0, 0.3, raters.participants)[raters.participant]
                  + raters.noise * rng.logistic(size=n_rows))
        cuts = np.linspace(strength.min() - 0.5, strength.max() + 0.5, 6)[1:-1]
        ratings = np.where(raters.random, rng.integers(1, 6, n_rows),
                           1 + np.searchsorted(cuts, latent))
        return {"rating": pd.array(ratings, dtype="Int64")}

    def answered(self, rows):
        ratings = pd.to_numeric(rows["rating"], errors="coerce")
        notes = []
        if ratings.isna().any():
            notes.append(f"{int(ratings.isna().sum())} clip(s) without a rating were left out")
        low, high = SCALE
        bad = ratings.notna() & ((ratings % 1 != 0) | (ratings < low) | (ratings > high))
        if bad.any():
            raise AnalysisError(f"{int(bad.sum())} rating(s) are not whole numbers from {low} to "
                                f"{high}, e.g. {ratings[bad].iloc[0]!r}")
        rows = rows.loc[ratings.notna().to_numpy()].copy()
        rows["rating"] = ratings.dropna().to_numpy(dtype=np.int64)
        return rows, notes

    def analyse(self, rows, config):
        names = sorted(rows["source"].unique())
        sources = mean_ratings(rows, config)
        values, groups = rows["rating"].to_numpy(), rows["source"].to_numpy()
        omnibus = stats.kruskal_wallis(values, groups, names)
        posthoc = stats.pairwise_mann_whitney(values, groups, names)
        sources = ranked_sources(sources)
        low, high = SCALE
        distribution = (pd.crosstab(rows["source"], rows["rating"], normalize="index")
                        .reindex(index=sources.index, columns=range(low, high + 1), fill_value=0.0))
        distribution.columns = [f"rating_{r}" for r in distribution.columns]
        distribution["n_judgements"] = sources["n_judgements"]
        tables = [
            Table("sources", f"Mean rating ({low}-{high}, higher = more realistic) with "
                  f"{config.confidence:.0%} intervals over participants (bootstrap)", sources),
            Table("rating_shares", "Share of each source's clips at each rating", distribution),
            Table("pairwise_tests", "Mann-Whitney U tests between sources (superiority: chance "
                  "that a rating of a beats one of b, ties half), Holm-corrected", posthoc),
        ]
        if "action" in rows.columns and rows["action"].nunique() > 1:
            by_action = mean_ratings(rows, config, by=("action", "source"))
            tables.append(Table("by_action", "Mean rating per action", by_action.reset_index()))
        methods = [
            f"For each source{_per_action(rows)} we report the mean rating, "
            f"{participant_bootstrap_text(config)}",
            f"sources were compared with a Kruskal-Wallis test (H({omnibus['df']}) = "
            f"{number(omnibus['statistic'], 2)}, {p_text(omnibus['p'])}) and pairwise "
            f"two-sided Mann-Whitney U tests with Holm's correction, which treat the ratings as "
            f"ordinal and count them as independent (with participants who differ, their "
            f"p-values are too small)",
        ]
        plots = [Plot("mean_rating", "Mean rating", _plot(sources))]
        return Analysis(measure="mean rating", sources=sources, tables=tables, plots=plots,
                        methods=methods, tests={"kruskal_wallis": omnibus})


@register_analysis("rating_reference")
class RatingReference(RatingStandards):
    """Each clip is rated 1-5 next to one real clip of the action (seed 004)."""

    design = ("each clip was rated from 1 to 5 (higher = more realistic) while one real clip of "
              "the same action was shown as a reference")

    def simulated_trials(self, rng, n_trials, n_sources, clips_per_trial):
        return rng.integers(0, n_sources, (n_trials, 1))


def mean_ratings(rows: pd.DataFrame, config, by=("source",)) -> pd.DataFrame:
    """Return ``score`` (mean rating), ``ci_low``/``ci_high`` over participants, ``sd`` and
    counts per group of ``by``.

    The interval resamples participants with all their ratings
    (:func:`analysis.stats.participant_bootstrap`; ``config`` gives the number of
    resamples, seed and confidence).
    """
    frame = source_counts(rows, by)
    groups = rows.groupby(list(by), observed=True)["rating"]
    frame["sd"] = groups.std(ddof=1)
    means = stats.bootstrap_means(rows, "rating", by, config.bootstrap, config.seed,
                                  config.confidence)
    frame = frame.join(means)
    return frame[["score", "ci_low", "ci_high", "sd", "n_participants", "n_judgements"]]


def _per_action(rows) -> str:
    return " (and each action)" if "action" in rows.columns and rows["action"].nunique() > 1 else ""


def _plot(sources):
    def draw():
        from analysis.figures import interval_figure

        return interval_figure(sources, "Mean rating (1-5)", bars=True, limits=SCALE)

    return draw
