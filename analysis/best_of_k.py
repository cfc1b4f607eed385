"""Best of K: the worth of each source from "which of these K clips is best?" answers.

A trial showing K clips whose participant picked one is a top-1 choice: under the
Plackett-Luce model (its top-1 case, the model of choix's ``ilsr_top1``), the clip of
source ``i`` is picked with probability ``w_i / sum_j w_j`` over the clips shown (a
source shown twice counts twice). The worths are fitted here by Hunter's MM algorithm
on choice counts, with a weak prior of ``PRIOR`` virtual wins and as many virtual losses
per source against a reference of worth 1 (as :mod:`analysis.worth`), which keeps every
worth finite; intervals and tests of differences treat participants and clips as random
(:mod:`analysis.crossed`), every replicate refitted at once.

Trials answered "all good" or "all bad" pick no clip: they leave the fit and are
reported as shares (with intervals over participants and clips), overall and per source shown.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from analysis import crossed, mixed
from analysis.counts import ranked_sources, source_counts
from analysis.registry import Analysis, Plot, StudyAnalysis, Table, register_analysis
from analysis.tables import AnalysisError

PICKS = ("best", "other", "all_good", "all_bad")
NONE_BEST = ("all_good", "all_bad")
PRIOR = 1.0
FEW_PARTICIPANTS = 10


class Choices:
    """Distinct top-1 choices: ``sets`` ``(E, K)`` how many clips of each source were
    shown, ``chosen`` ``(E,)`` the source picked, ``counts`` ``(P, E)`` how often each
    participant made each choice."""

    def __init__(self, shown: np.ndarray, chosen: np.ndarray, participants: np.ndarray,
                 n_sources: int, n_participants: int):
        shown = np.asarray(shown, dtype=np.int64)  # (T, K) source counts per trial
        keyed = np.concatenate([shown, np.asarray(chosen, dtype=np.int64)[:, None]], axis=1)
        unique, inverse = np.unique(keyed, axis=0, return_inverse=True)
        inverse = inverse.ravel()
        self.sets = unique[:, :-1].astype(float)
        self.chosen = unique[:, -1]
        self.n_sources = n_sources
        self.counts = np.zeros((n_participants, len(unique)))
        np.add.at(self.counts, (np.asarray(participants, dtype=np.int64), inverse), 1.0)
        self.one_hot = np.zeros((len(unique), n_sources))
        self.one_hot[np.arange(len(unique)), self.chosen] = 1.0


def fit_top1(sets, chosen_one_hot, counts, prior: float = PRIOR, iterations: int = 5000,
             tolerance: float = 1e-9) -> np.ndarray:
    """Return log-worths ``(B, K)``, centred, for choice counts ``counts`` ``(B, E)``.

    Hunter's MM update for Luce choices: ``w_i <- wins_i / sum_e c_e n_ei / W_e`` (``W_e``
    the worth shown at choice ``e``), with the prior's virtual choices between ``i`` and
    a reference of worth 1 added to both sums. ``prior=0`` is the plain maximum
    likelihood (finite only when every source both wins and loses).
    """
    counts = np.atleast_2d(np.asarray(counts, dtype=float))
    wins = counts @ chosen_one_hot + prior  # (B, K)
    w = np.ones((len(counts), sets.shape[1]))
    for _ in range(iterations):
        shown = w @ sets.T  # (B, E)
        with np.errstate(invalid="ignore", divide="ignore"):
            per = np.where(shown > 0, counts / shown, 0.0)
        denominator = per @ sets + 2 * prior / (w + 1.0)
        new = np.where(denominator > 0, wins / np.maximum(denominator, 1e-300), w)
        if prior == 0:
            new /= np.exp(np.log(new).mean(axis=1, keepdims=True))
        change = np.abs(np.log(new) - np.log(w)).max()
        w = new
        if change < tolerance:
            break
    theta = np.log(w)
    return theta - theta.mean(axis=1, keepdims=True)


def log_likelihood(sets, chosen, counts, theta) -> float:
    """Return the top-1 Plackett-Luce log-likelihood of ``theta`` ``(K,)`` (no prior)."""
    theta = np.asarray(theta, dtype=float)
    shift = theta.max()
    log_shown = np.log(np.asarray(sets, dtype=float) @ np.exp(theta - shift)) + shift
    return float(np.asarray(counts, dtype=float) @ (theta[np.asarray(chosen)] - log_shown))


def top1_worth(shown, chosen, rows: pd.DataFrame, config) -> crossed.Crossed:
    """Return the crossed bootstrap of the top-1 log-worths of the trials that picked a
    clip: ``shown`` ``(T, K)`` source counts, ``chosen`` ``(T,)`` the source picked, and
    ``rows`` those trials' rows (in the same trial order). Each trial is a unit, weighed
    by its participant's and all its clips' draws, every replicate refitted at once."""
    choices = Choices(shown, chosen, np.arange(len(shown)), shown.shape[1], len(shown))

    def finish(counts):
        return fit_top1(choices.sets, choices.one_hot, counts)

    statistic = crossed.Linear(choices.counts, finish)
    return crossed.bootstrap(crossed.design(rows, unit="trial_key"), statistic, config)


@register_analysis("best_of_k")
class BestOfK(StudyAnalysis):
    """Each trial shows K clips of one action; the participant picks the best, or says
    all are good or all are bad."""

    answer = "pick"
    mixed_model = "worth"
    design = ("each trial showed clips of one action from the sources in random order, and "
              'participants chose the best clip, or answered "all good" or "all bad" when none '
              "stood out")
    extra_columns = ("pick",)

    def simulated_trials(self, rng, n_trials, n_sources, clips_per_trial):
        """``clips_per_trial`` clips of distinct sources (at most one per source)."""
        k = min(clips_per_trial, n_sources)
        return np.argsort(rng.random((n_trials, n_sources)), axis=1)[:, :k]

    def simulated_answers(self, raters):
        """Pick the best by quality + Gumbel noise (a Plackett-Luce top-1 draw); ``tie_rate``
        of trials are answered all good (mean quality above the middle) or all bad."""
        rng, m = raters.rng, raters.m
        utility = (np.where(raters.random, 0.0, raters.quality)
                   + raters.noise * rng.gumbel(size=raters.n_rows)).reshape(-1, m)
        picks = np.full(utility.shape, "other", dtype=object)
        picks[np.arange(len(utility)), utility.argmax(axis=1)] = "best"
        careless = raters.random.reshape(-1, m)[:, 0]
        tie = (rng.random(len(utility)) < raters.tie_rate) & ~careless
        good = raters.quality.reshape(-1, m).mean(axis=1) > raters.middle
        picks[tie] = np.where(good[tie], "all_good", "all_bad")[:, None]
        return {"pick": picks.ravel()}

    def worth_choices(self, rows):
        """Return one Luce choice per trial that picked a clip: its source among the
        sources of the trial's clips ("all good" and "all bad" pick none), with the
        trial's clips (``among_clips``, aligned with ``among``) and its participant."""
        trials = rows.groupby("trial_key", sort=False)
        best = rows.loc[rows["pick"].astype(str).to_numpy() == "best"]
        best = best.drop_duplicates("trial_key")
        keys = best["trial_key"]
        choices = pd.DataFrame({"chosen": best["source"].to_numpy(),
                                "among": trials["source"].agg(tuple).reindex(keys).to_numpy(),
                                "weight": 1.0})
        if {"stimulus", "pcode"} <= set(rows.columns):
            choices["among_clips"] = trials["stimulus"].agg(tuple).reindex(keys).to_numpy()
            choices["participant"] = best["pcode"].to_numpy()
        return choices

    def answered(self, rows):
        """Return the rows of trials with a valid answer: one clip ``best`` and the rest
        ``other``, or every clip ``all_good`` (or ``all_bad``)."""
        notes = []
        picks = rows["pick"].astype("string")
        if picks.isna().any():
            notes.append(f"{int(picks.isna().sum())} clip(s) of trials without an answer were "
                         f"left out")
        bad = picks.notna() & ~picks.isin(PICKS)
        if bad.any():
            raise AnalysisError(f"{int(bad.sum())} row(s) have a pick that is none of "
                                f"{', '.join(PICKS)}, e.g. {picks[bad].iloc[0]!r}")
        rows = rows.loc[picks.notna().to_numpy()].copy()
        rows["pick"] = picks.dropna().astype(str).to_numpy()
        trial = pd.factorize(rows["trial_key"])[0]
        counts = np.zeros((int(trial.max()) + 1 if len(trial) else 0, len(PICKS)), dtype=np.int64)
        np.add.at(counts, (trial, pd.Categorical(rows["pick"], categories=PICKS).codes), 1)
        best, other, good, bad = counts.T
        picked = (best == 1) & (good == 0) & (bad == 0)
        none = (best == 0) & (other == 0) & ((good > 0) != (bad > 0))
        valid = picked | none
        if not valid.all():
            raise AnalysisError(f"{int((~valid).sum())} trial(s) have no single clip picked as "
                                f"best nor all clips answered all_good or all_bad")
        return rows, notes

    def analyse(self, rows, config):
        names = sorted(rows["source"].unique())
        n_participants = int(rows["pcode"].max()) + 1
        code = pd.Categorical(rows["source"], categories=names).codes
        trial = pd.factorize(rows["trial_key"])[0]
        n_trials = int(trial.max()) + 1
        shown = np.zeros((n_trials, len(names)), dtype=np.int64)
        np.add.at(shown, (trial, code), 1)
        first = np.unique(trial, return_index=True)[1]
        verdict = np.full(n_trials, "pick", dtype=object)
        verdict[trial[first]] = rows["pick"].to_numpy()[first]
        verdict = np.where(np.isin(verdict, NONE_BEST), verdict, "pick")
        is_best = rows["pick"].to_numpy() == "best"
        chosen = np.full(n_trials, -1)
        chosen[trial[is_best]] = code[is_best]
        participant = np.zeros(n_trials, dtype=np.int64)
        participant[trial] = rows["pcode"].to_numpy()
        picked = chosen >= 0
        if not picked.any():
            raise AnalysisError('no trial picked a clip (every answer is "all good" or "all bad"): '
                                "there is nothing to fit worths to")
        picked_rows = np.isin(trial, np.flatnonzero(picked))
        result = top1_worth(shown[picked], chosen[picked], rows.loc[picked_rows], config)
        shown_result = crossed.report(result, names, rows.loc[picked_rows], config)
        fitted = shown_result.scores

        sources = source_counts(rows)
        sources = sources.join(fitted[["score", "ci_low", "ci_high"]])
        # How often a shown clip of the source was picked, and its expected share under
        # the fit (both per clip shown, in trials that picked a clip).
        frame = pd.DataFrame({"source": rows["source"].to_numpy()[picked_rows],
                              "best": is_best[picked_rows]})
        sources["best_share"] = frame.groupby("source")["best"].mean()
        per_source = {}
        for verdict_name in NONE_BEST:
            in_trials = np.isin(trial, np.flatnonzero(verdict == verdict_name))
            per_source[f"{verdict_name}_share"] = (
                pd.Series(in_trials, index=rows.index).groupby(rows["source"].to_numpy()).mean())
        for name, series in per_source.items():
            sources[name] = series
        sources = ranked_sources(sources)[["score", "ci_low", "ci_high", "best_share",
                                           "all_good_share", "all_bad_share", "n_participants",
                                           "n_judgements"]]

        answers = _answer_shares(verdict, rows, config)
        tables = [
            Table("sources", "Plackett-Luce (top-1) worth (log scale, 0 = average source) with "
                  f"{config.confidence:.0%} intervals over participants and clips, the share of "
                  'shown clips picked as best, and the share of all-good and all-bad trials '
                  "that showed the source", sources),
            Table("differences", "Difference of top-1 worths a - b, t test over participants "
                  "and clips (Holm), and the shares of its variance from participants, clips "
                  "and single answers", shown_result.differences[crossed.DIFFERENCE_COLUMNS]),
            Table("answers", "Share of trials with a clip picked, all good and all bad, "
                  f"with {config.confidence:.0%} intervals over participants and clips", answers),
            Table("clips", "Clips per source, and per source and condition", shown_result.clips),
        ]
        notes = list(shown_result.notes)
        if n_participants < FEW_PARTICIPANTS:
            notes.append(f"only {n_participants} participant(s): with fewer than "
                         f"{FEW_PARTICIPANTS} the bootstrap over participants gives unreliable "
                         "intervals")
        if "action" in rows.columns and rows["action"].nunique() > 1:
            tables.append(Table("by_action", "Plackett-Luce (top-1) worth per action",
                                self._by_action(rows, shown, chosen, trial, names, config)))
        share_none = answers.set_index("answer")["share"]
        methods = [
            (f"Each trial that picked a clip was read as a top-1 choice among the clips shown, "
             f"and a Plackett-Luce worth per source was fitted to these choices by "
             f"minorisation-maximisation (log scale, centred on 0; a weak prior of one virtual "
             f"win and one virtual loss per source against a reference keeps estimates "
             f"finite), refitted in every bootstrap resample; sources were compared by the "
             f"differences of their worths"),
            shown_result.method,
            (f'{share_none.get("all_good", 0):.0%} of trials were answered "all good" and '
             f'{share_none.get("all_bad", 0):.0%} "all bad"; these pick no clip and do not '
             f"enter the worths"),
        ]
        picked_frame = rows.loc[picked_rows]
        model_tables, model_methods, model_notes, model = mixed.worth_tables(
            mixed.ranked_pairs(picked_frame.assign(
                order=np.where(picked_frame["pick"].to_numpy() == "best", 1, 2)), "order"),
            names, config, sources["score"], measure="Plackett-Luce (top-1) worth",
            reading="the clip picked as best against each other clip of its trial: under "
                    "Plackett-Luce, given that one of two clips was picked, it is the one "
                    "Bradley-Terry with the same worths prefers",
            clustered=True, checkpoints=mixed.clip_checkpoints(rows))
        tables += model_tables
        methods += model_methods
        notes += model_notes
        tests = {"answers": answers, "differences": shown_result.differences}
        if model:
            tests["mixed_model"] = model["differences"]
        plots = [Plot("worth", "Plackett-Luce (top-1) worth", _worth_plot(sources))]
        return Analysis(measure="Plackett-Luce top-1 worth (log scale)", sources=sources,
                        tables=tables, plots=plots, methods=methods, notes=notes,
                        tests=tests)

    def _by_action(self, rows, shown, chosen, trial, names, config):
        action = np.empty(len(shown), dtype=object)
        action[trial] = rows["action"].astype(str).to_numpy()
        frames = []
        for name in sorted(set(action)):
            mine = (action == name) & (chosen >= 0)
            present = shown[action == name].sum(axis=0) > 0
            counts = source_counts(rows.loc[rows["action"].astype(str).to_numpy() == name])
            if mine.any() and present.sum() > 1:
                keep = np.flatnonzero(present)
                remap = np.full(len(names), -1)
                remap[keep] = np.arange(len(keep))
                subset = rows.loc[np.isin(trial, np.flatnonzero(mine))]
                result = top1_worth(shown[mine][:, keep], remap[chosen[mine]], subset, config)
                fitted = crossed.scores(result, [names[i] for i in keep], config.confidence)
                counts = counts.join(fitted[["score", "ci_low", "ci_high"]])
            counts.insert(0, "action", name)
            frames.append(counts.reset_index())
        columns = ["action", "source", "score", "ci_low", "ci_high", "n_participants",
                   "n_judgements"]
        return pd.concat(frames, ignore_index=True).reindex(columns=columns)


def _answer_shares(verdict, rows: pd.DataFrame, config) -> pd.DataFrame:
    """Return the share of trials of each kind of answer (``verdict`` per trial, in the
    trial order of ``rows``), with intervals over participants and clips."""
    n = len(verdict)
    labels = {"pick": "a clip picked as best", "all_good": "all good", "all_bad": "all bad"}
    counts = np.array([(verdict == name).sum() for name in labels])
    design = crossed.design(rows, unit="trial_key")
    low, high = [], []
    for name in labels:
        result = crossed.bootstrap(design, crossed.ratio((verdict == name).astype(float),
                                                         np.zeros(n), 1),
                                   config)
        row = result.summary(config.confidence, bounds=(0, 1)).iloc[0]
        low.append(row["ci_low"])
        high.append(row["ci_high"])
    return pd.DataFrame({"answer": list(labels), "meaning": list(labels.values()),
                         "trials": counts, "share": counts / n, "ci_low": low, "ci_high": high})


def _worth_plot(sources):
    def draw():
        from analysis.figures import interval_figure

        return interval_figure(sources, "Plackett-Luce top-1 log-worth", reference=0.0)

    return draw
