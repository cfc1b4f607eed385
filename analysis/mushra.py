"""MUSHRA: clips scored 0-100 beside a hidden reference and a low anchor (ITU-R BS.1534).

The hidden reference (rows whose ``stimulus_role`` is ``reference``) and the low anchor
(``anchor``) are conditions of their own, ``hidden_reference`` and ``anchor``, whatever
their source. Before the statistics the recommendation's post-screening leaves out a
participant who scores the hidden reference below ``screen_threshold`` (90) in more than
``screen_share`` (15 %) of their trials (:meth:`Mushra.screen`; the study's options when
analysed with its study).

Each participant contributes one number per condition, their mean score (as the
recommendation analyses MUSHRA data); a condition's score is the mean over participants,
with an interval over participants and clips (:mod:`analysis.crossed`). Conditions are
compared by the differences of these means, t tests over participants and clips,
Holm-corrected.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from analysis import crossed, mixed, simulate
from analysis.counts import ranked_sources, source_counts
from analysis.registry import Analysis, Plot, StudyAnalysis, Table, register_analysis
from analysis.tables import AnalysisError

SCALE = (0, 100)
SCREEN_THRESHOLD = 90
SCREEN_SHARE = 0.15
HIDDEN_REFERENCE, ANCHOR = "hidden_reference", "anchor"
ROLES = {"reference": HIDDEN_REFERENCE, "anchor": ANCHOR}


def screening_rule(config) -> tuple[int, float]:
    """Return the post-screening threshold and share: the study's options, else 90 and 15 %."""
    options = getattr(config, "type_options", None) or {}
    threshold = options.get("screen_threshold", SCREEN_THRESHOLD)
    share = options.get("screen_share", SCREEN_SHARE)
    return int(threshold), float(share)


def reference_failures(rows: pd.DataFrame, threshold: int) -> pd.DataFrame:
    """Return per participant (``pcode``) the trials with a hidden reference, how many
    scored it below ``threshold``, and that share."""
    reference = rows.loc[rows["source"] == HIDDEN_REFERENCE]
    per_trial = reference.groupby(["pcode", "trial_key"])["score"].min()
    failed = (per_trial < threshold).groupby(level="pcode")
    frame = pd.DataFrame({"trials": failed.size(), "failed": failed.sum()})
    frame["share_failed"] = frame["failed"] / frame["trials"]
    return frame


def participant_means(rows: pd.DataFrame) -> pd.DataFrame:
    """Return ``(participants, conditions)``: each participant's mean score per condition."""
    return rows.groupby(["pcode", "source"])["score"].mean().unstack("source")


@register_analysis("mushra")
class Mushra(StudyAnalysis):
    """Each trial scores one action's clips 0-100 at once, with a hidden reference and a
    low anchor among them."""

    answer = "score"
    mixed_model = "linear"
    agreement_level = "interval"
    design = ("each trial showed clips of one action side by side, with a hidden real reference "
              "and a low anchor (a degraded real clip) among them, and participants scored every "
              "clip from 0 (bad) to 100 (excellent) on sliders (MUSHRA)")
    extra_columns = ("stimulus_role", "score")
    # Share of trials in which a simulated attentive rater misses the hidden reference.
    simulated_slips = 0.02

    def simulated_sources(self, names, strength):
        """Add the hidden reference (above the best source) and the low anchor (below the
        worst) as two more sources."""
        return (np.append(names, ["reference", "anchor"]),
                np.append(strength, [strength.max() + 1.0, strength.min() - 2.0]))

    def simulated_trials(self, rng, n_trials, n_sources, clips_per_trial):
        return simulate.every_source(n_trials, n_sources)

    def simulated_answers(self, raters):
        """Score each clip ``100 sigmoid(quality + rater bias + logistic noise - centre)``;
        an attentive rater scores the hidden reference 90-100 but in ``simulated_slips``
        of trials."""
        rng, n_rows = raters.rng, raters.n_rows
        latent = (raters.quality + rng.normal(0.0, 0.3, raters.participants)[raters.participant]
                  + raters.noise * rng.logistic(size=n_rows))
        scores = 100 / (1 + np.exp(-(latent - raters.centre)))
        reference = ((raters.row_source == raters.n_sources - 2)
                     & (rng.random(n_rows) >= self.simulated_slips))
        scores = np.where(reference, rng.uniform(90, 100, n_rows), scores)
        scores = np.where(raters.random, rng.uniform(0, 100, n_rows), scores)
        return {"score": pd.array(np.rint(scores).astype(np.int64), dtype="Int64")}

    def simulated_roles(self, is_catch, row_source, n_sources):
        return np.select([is_catch, row_source == n_sources - 2, row_source == n_sources - 1],
                         ["catch", "reference", "anchor"], "judged")

    def answered(self, rows):
        """Return the scored rows, scores whole numbers 0..100, the hidden reference and
        the anchor as conditions of their own (``source``)."""
        notes = []
        scores = pd.to_numeric(rows["score"], errors="coerce")
        if scores.isna().any():
            notes.append(f"{int(scores.isna().sum())} clip(s) without a score were left out")
        low, high = SCALE
        bad = scores.notna() & ((scores % 1 != 0) | (scores < low) | (scores > high))
        if bad.any():
            raise AnalysisError(f"{int(bad.sum())} score(s) are not whole numbers from {low} to "
                                f"{high}, e.g. {scores[bad].iloc[0]!r}")
        rows = rows.loc[scores.notna().to_numpy()].copy()
        rows["score"] = scores.dropna().to_numpy(dtype=np.int64)
        if "stimulus_role" in rows.columns:
            roles = rows["stimulus_role"].astype("string").map(ROLES)
            rows["source"] = roles.fillna(rows["source"]).astype(str).to_numpy()
        else:
            notes.append("the table has no stimulus_role column: the hidden reference and the "
                         "anchor cannot be told from the sources, and no post-screening was done")
        return rows, notes

    def screen(self, rows, config):
        threshold, share = screening_rule(config)
        rule = (f"Scored the hidden reference below {threshold} in more than {share:.0%} of "
                f"trials (MUSHRA post-screening)")
        failures = reference_failures(rows, threshold)
        ids = (rows.groupby("pcode")["participant"].first()
               if "participant" in rows.columns else None)
        self.screening = failures.assign(excluded=failures["share_failed"] > share)
        if ids is not None:
            self.screening.index = ids.reindex(self.screening.index).to_numpy()
        self.screening.index.name = "participant"
        if failures.empty:
            record = {"rule": rule, "applied": "skipped (no hidden reference)", "participants": 0,
                      "trials": 0, "judgements": 0}
            return rows, [record], []
        flagged = rows["pcode"].isin(failures.index[failures["share_failed"] > share]).to_numpy()
        record = {"rule": rule, "applied": "yes" if config.exclusions else "no (--no-exclusions)",
                  "participants": int(rows.loc[flagged, "pcode"].nunique()),
                  "trials": int(rows.loc[flagged, "trial_key"].nunique()),
                  "judgements": int(flagged.sum())}
        notes = []
        if config.exclusions and flagged.all():
            raise AnalysisError(f"every participant fails the post-screening ({rule.lower()}); "
                                f"try --no-exclusions to see them all")
        if config.exclusions:
            rows = rows.loc[~flagged]
        return rows, [record], notes

    def analyse(self, rows, config):
        means = participant_means(rows)
        sources = source_counts(rows)
        sources["score"] = means.mean(axis=0)
        sources["sd"] = means.std(axis=0, ddof=1)
        sources["median"] = means.median(axis=0)
        names = sorted(means.columns)
        # Each row weighs 1 / (the participant's rows of its condition): a condition's
        # mean is then the mean over participants of their means.
        per_cell = rows.groupby(["pcode", "source"])["score"].transform("size").to_numpy(dtype=float)
        result, _ = crossed.group_means(rows, "score", config, base=1.0 / per_cell)
        shown = crossed.report(result, names, rows, config)
        sources = sources.join(crossed.intervals(result, pd.Index(names), config, bounds=SCALE)
                               [["ci_low", "ci_high"]])
        sources["condition"] = [
            {HIDDEN_REFERENCE: "hidden reference", ANCHOR: "low anchor"}.get(s, "source")
            for s in sources.index]
        sources = ranked_sources(sources)[["score", "ci_low", "ci_high", "sd", "median",
                                           "condition", "n_participants", "n_judgements"]]
        tables = [Table("sources", "Mean over participants of each participant's mean score "
                        f"(0-100) with {config.confidence:.0%} intervals over participants and "
                        "clips", sources),
                  Table("differences", "Difference of mean scores a - b, t test over "
                        "participants and clips (Holm), and the shares of its variance from "
                        "participants, clips and single answers",
                        shown.differences[crossed.DIFFERENCE_COLUMNS]),
                  Table("clips", "Clips per condition, and per condition and action", shown.clips)]
        tests, notes = {"differences": shown.differences}, list(shown.notes)
        methods = ["conditions were compared by the differences of their mean scores", shown.method]
        model_tables, model_methods, model_notes, fitted = mixed.linear_tables(
            rows, "score", config, "score")
        tables += model_tables
        methods += model_methods
        notes += model_notes
        if fitted:
            tests["mixed_model"] = fitted["differences"]
        screening = getattr(self, "screening", None)
        threshold, share = screening_rule(config)
        if screening is not None and not screening.empty:
            frame = screening.reset_index()
            tables.append(Table("post_screening", f"Hidden reference scored below {threshold}, "
                                f"per participant (excluded above {share:.0%} of trials)", frame))
        methods.insert(0, (
            f"For each condition (the sources, the hidden reference and the low anchor) we "
            f"report the mean over participants of each participant's mean score; following the MUSHRA recommendation, participants who "
            f"scored the hidden reference below {threshold} in more than {share:.0%} of trials "
            f"were excluded beforehand"))
        plots = [Plot("mean_score", "Mean score (0-100)", _plot(sources))]
        return Analysis(measure="mean MUSHRA score (0-100)", sources=sources, tables=tables,
                        plots=plots, methods=methods, notes=notes, tests=tests)


def _plot(sources):
    def draw():
        from analysis.figures import interval_figure

        return interval_figure(sources, "Mean score (0-100)", bars=True, limits=SCALE)

    return draw
