"""Realism ratings 1-5: the mean score per source (seed 003, Table 3; seed 004, Table 5).

Means come with intervals over participants and clips (:mod:`analysis.crossed`: a
participant's ratings stay together, a clip's ratings too, and both are redrawn);
sources are compared by the differences of their means with the same standard errors,
Holm-corrected. (Rank tests across all ratings, such as Kruskal-Wallis, would treat a
within-subject design's ratings as independent.)
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from analysis import crossed, mixed, simulate
from analysis.counts import ranked_sources, source_counts
from analysis.registry import Analysis, Plot, StudyAnalysis, Table, register_analysis
from analysis.tables import AnalysisError

SCALE = (1, 5)


@register_analysis("rating_standards")
class RatingStandards(StudyAnalysis):
    """Each clip is rated 1-5 after scoring standards with example clips (seed 003)."""

    answer = "rating"
    mixed_model = "linear"
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
        result, _ = crossed.group_means(rows, "rating", config)
        shown = crossed.report(result, names, rows, config)
        sources = mean_ratings(rows, config, result)
        sources = ranked_sources(sources)
        low, high = SCALE
        distribution = (pd.crosstab(rows["source"], rows["rating"], normalize="index")
                        .reindex(index=sources.index, columns=range(low, high + 1), fill_value=0.0))
        distribution.columns = [f"rating_{r}" for r in distribution.columns]
        distribution["n_judgements"] = sources["n_judgements"]
        tables = [
            Table("sources", f"Mean rating ({low}-{high}, higher = more realistic) with "
                  f"{config.confidence:.0%} intervals over participants and clips", sources),
            Table("rating_shares", "Share of each source's clips at each rating", distribution),
            Table("differences", "Difference of mean ratings a - b, t test over participants "
                  "and clips (Holm), and the shares of its variance from participants, clips "
                  "and single answers", shown.differences[crossed.DIFFERENCE_COLUMNS]),
            Table("clips", "Clips per source, and per source and condition", shown.clips),
        ]
        if "action" in rows.columns and rows["action"].nunique() > 1:
            by_action = mean_ratings(rows, config, by=("action", "source"))
            tables.append(Table("by_action", "Mean rating per action", by_action.reset_index()))
        methods = [
            f"For each source{_per_action(rows)} we report the mean rating; sources were compared "
            f"by the differences of their mean ratings",
            shown.method,
        ]
        model_tables, model_methods, model_notes, fitted = mixed.linear_tables(
            rows, "rating", config, "rating")
        tables += model_tables
        methods += model_methods
        tests = {"differences": shown.differences}
        if fitted:
            tests["mixed_model"] = fitted["differences"]
        plots = [Plot("mean_rating", "Mean rating", _plot(sources))]
        return Analysis(measure="mean rating", sources=sources, tables=tables, plots=plots,
                        methods=methods, notes=shown.notes + model_notes, tests=tests)


@register_analysis("rating_reference")
class RatingReference(RatingStandards):
    """Each clip is rated 1-5 next to one real clip of the action (seed 004)."""

    design = ("each clip was rated from 1 to 5 (higher = more realistic) while one real clip of "
              "the same action was shown as a reference")

    def simulated_trials(self, rng, n_trials, n_sources, clips_per_trial):
        return rng.integers(0, n_sources, (n_trials, 1))


def mean_ratings(rows: pd.DataFrame, config, result=None, by=("source",)) -> pd.DataFrame:
    """Return ``score`` (mean rating), ``ci_low``/``ci_high`` over participants and clips,
    ``sd`` and counts per group of ``by``.

    ``result`` is the crossed bootstrap of these means when already drawn
    (:func:`analysis.crossed.group_means`; ``config`` gives the number of resamples,
    seed and confidence).
    """
    frame = source_counts(rows, by)
    groups = rows.groupby(list(by), observed=True)["rating"]
    frame["sd"] = groups.std(ddof=1)
    if result is None:
        result, index = crossed.group_means(rows, "rating", config, by)
    else:
        index = frame.index
    frame = frame.join(crossed.intervals(result, index, config, bounds=SCALE))
    return frame[["score", "ci_low", "ci_high", "sd", "n_participants", "n_judgements"]]


def _per_action(rows) -> str:
    return " (and each action)" if "action" in rows.columns and rows["action"].nunique() > 1 else ""


def _plot(sources):
    def draw():
        from analysis.figures import interval_figure

        return interval_figure(sources, "Mean rating (1-5)", bars=True, limits=SCALE)

    return draw
