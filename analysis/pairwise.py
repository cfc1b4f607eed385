"""Pairwise preference: two clips side by side, the better one (or both good, both bad).

Reported: the win rate of each pair of sources over the comparisons one of them won
(tested against 50 %, Holm-corrected), Bradley-Terry worths (ties left out) and their
differences, and the left/right position bias; every interval and test treats
participants and clips as random (:mod:`analysis.crossed`).
"""

from __future__ import annotations

import itertools

import numpy as np
import pandas as pd

from analysis import crossed, mixed, simulate, stats
from analysis.counts import ranked_sources, source_counts
from analysis.formatting import estimate_with_interval, p_text, plural
from analysis.registry import (Analysis, AnswerOption, Plot, StudyAnalysis, Table, offered,
                               register_analysis)
from analysis.tables import AnalysisError

CHOICES = ("left", "right", "both_good", "both_bad")


@register_analysis("pairwise")
class Pairwise(StudyAnalysis):
    """Each trial shows two clips; the participant picks one, or says both good / both bad."""

    answer = "choice"
    mixed_model = "worth"
    agreement_level = "nominal"
    required = ("position",)
    design = ("each trial showed two clips of one action side by side and participants chose the "
              "better one")
    answer_options = {"allow_ties": AnswerOption(
        CHOICES[2:], ", or answered that both were equally good or equally bad",
        ("both good", "both bad", "equally good", "equally bad", "tie"))}

    def simulated_trials(self, rng, n_trials, n_sources, clips_per_trial):
        return simulate.pairs(rng, n_trials, n_sources)

    def simulated_answers(self, raters):
        """Left wins with probability sigmoid((q_left - q_right + position_bias) / noise);
        ``tie_rate`` of comparisons are called both good (mean quality above the middle)
        or both bad."""
        rng = raters.rng
        q_left, q_right, careless = simulate.left_right(raters)
        chance = simulate.sigmoid((q_left - q_right + raters.position_bias) / raters.noise)
        chance = np.where(careless, 0.5, chance)
        picks = np.where(rng.random(len(q_left)) < chance, "left", "right").astype(object)
        tie = (rng.random(len(q_left)) < raters.tie_rate) & ~careless
        picks[tie] = np.where((q_left + q_right)[tie] / 2 > raters.middle, "both_good", "both_bad")
        return {"choice": pd.Categorical(np.repeat(picks, raters.m))}

    def answered(self, rows):
        return comparisons_answered(rows, CHOICES)

    def judgement_values(self, rows):
        """Return one value per comparison: its pair of clips (in a fixed order) and the
        answer relative to that order: 0 the first clip won, 1 the second, 2 both good,
        3 both bad."""
        trials = comparisons(rows, sorted(rows["source"].unique()))
        left, right = trials["left_stimulus"], trials["right_stimulus"]
        if pd.api.types.is_integer_dtype(left) and pd.api.types.is_integer_dtype(right):
            left, right = left.to_numpy(np.int64), right.to_numpy(np.int64)
            # Stimulus ids are database keys: two fit in one integer.
            unit = np.minimum(left, right) * (1 << 32) + np.maximum(left, right)
        else:
            left, right = left.astype(str).to_numpy(object), right.astype(str).to_numpy(object)
            unit = np.where(left <= right, left + "|" + right, right + "|" + left)
        first_is_left = left <= right
        choice = trials["choice"].to_numpy()
        value = np.where(choice >= 2, choice, np.where(first_is_left, choice, 1 - choice))
        return pd.DataFrame({"participant": trials["pcode"].to_numpy(), "unit": unit, "value": value})

    def worth_comparisons(self, rows):
        """Return the decided comparisons (ties left out, as the worths leave them)."""
        names = np.array(sorted(rows["source"].unique()), dtype=object)
        trials = comparisons(rows, list(names))
        decided = trials.loc[trials["winner"] >= 0]
        left_won = (decided["winner"] == decided["left"]).to_numpy()
        left, right = decided["left_stimulus"].to_numpy(), decided["right_stimulus"].to_numpy()
        return pd.DataFrame({"winner": names[decided["winner"].to_numpy()],
                             "loser": names[decided["loser"].to_numpy()],
                             "weight": 1.0,
                             "winner_clip": np.where(left_won, left, right),
                             "loser_clip": np.where(left_won, right, left),
                             "participant": decided["pcode"].to_numpy()})

    def analyse(self, rows, config):
        names = sorted(rows["source"].unique())
        trials = comparisons(rows, names)
        decided_rows = decided_trial_rows(rows, trials)
        decided = trials.loc[trials["winner"] >= 0].reset_index(drop=True)
        design = crossed.design(decided_rows, unit="trial_key")
        fitted = bradley_terry(decided, decided_rows, names, config)
        shown = crossed.report(fitted, names, decided_rows, config)
        sources = source_counts(rows).join(shown.scores[["score", "ci_low", "ci_high"]])
        wins = np.bincount(decided["winner"], minlength=len(names))
        played = (np.bincount(decided["left"], minlength=len(names))
                  + np.bincount(decided["right"], minlength=len(names)))
        with np.errstate(invalid="ignore", divide="ignore"):
            sources["win_rate"] = pd.Series(wins / played, index=names)
        sources = ranked_sources(sources)[["score", "ci_low", "ci_high", "win_rate", "n_participants",
                                           "n_judgements"]]
        pairs, matrix = win_rates(trials, design, names, config)
        bias = position_bias(decided, design, config)
        ties = int((trials["winner"] < 0).sum())
        tables = [
            Table("sources", f"Bradley-Terry worth (log scale, 0 = average source) with "
                  f"{config.confidence:.0%} intervals over participants and clips, and the share "
                  f"of decided comparisons won", sources),
            Table("differences", "Difference of Bradley-Terry worths a - b, t test over "
                  "participants and clips (Holm), and the shares of its variance from "
                  "participants, clips and single answers",
                  shown.differences[crossed.DIFFERENCE_COLUMNS]),
            Table("win_rates", f"Win rate of a over b among decided comparisons, {config.confidence:.0%} "
                  f"intervals over participants and clips, t test against 50 % (Holm)", pairs),
            Table("position_bias", "Share of decided comparisons won by the left clip, with "
                  "its interval over participants and clips",
                  pd.DataFrame([bias])),
            Table("clips", "Clips per source, and per source and condition", shown.clips),
        ]
        if "action" in rows.columns and rows["action"].nunique() > 1:
            tables.append(Table("by_action", "Bradley-Terry worth per action",
                                self._by_action(rows, decided, decided_rows, names, config)))
        if offered(config, "allow_ties", ties):
            tied = (f"; {plural(ties, 'comparison')} answered 'both good' or 'both bad' "
                    f"{'counts' if ties == 1 else 'count'} as {'a tie' if ties == 1 else 'ties'} "
                    f"and {'is' if ties == 1 else 'are'} left out of win rates and worths")
        else:
            tied = ""
        methods = [
            f"For each pair of sources we report the share of comparisons won by each, tested "
            f"against 50 %{tied}",
            "a Bradley-Terry worth per source was fitted to the decided comparisons (log scale, "
            "centred on 0, with a weak prior of one virtual win and loss per source), and refitted "
            "in every bootstrap resample",
            shown.method,
            f"position bias: the left clip won "
            f"{estimate_with_interval(bias['share_left'], bias['ci_low'], bias['ci_high'], 3)} of "
            f"{plural(bias['n_decided'], 'decided comparison')} (t test against 0.5 over participants and "
            f"clips: {p_text(bias['p'])})",
        ]
        model_tables, model_methods, model_notes, model = mixed.worth_tables(
            sided_pairs(decided, names), names, config, sources["score"],
            measure="Bradley-Terry worth", reading="the decided comparisons, the left clip first",
            sided=True, checkpoints=mixed.clip_checkpoints(rows))
        tables += model_tables
        methods += model_methods
        tests = {"position_bias": bias, "ties": ties, "differences": shown.differences}
        if model:
            tests["mixed_model"] = model["differences"]
        plots = [
            Plot("worth", "Bradley-Terry worth", _worth_plot(sources)),
            Plot("win_matrix", "Win rate of each source (row) against each other (column)",
                 _matrix_plot(matrix.loc[sources.index, sources.index])),
        ]
        return Analysis(measure="Bradley-Terry worth (log scale)", sources=sources, tables=tables,
                        plots=plots, methods=methods, notes=shown.notes + model_notes,
                        tests=tests)

    def _by_action(self, rows, decided, decided_rows, names, config):
        frames = []
        actions = rows["action"].to_numpy()
        for action, group in decided.groupby("action", sort=True):
            present = np.unique(np.concatenate([group["left"], group["right"]]))
            frame = source_counts(rows.loc[actions == action])
            if len(present) > 1:
                subset = decided_rows.loc[(decided_rows["action"] == action).to_numpy()]
                fitted = bradley_terry(group.reset_index(drop=True), subset, names, config, present)
                scores = crossed.scores(fitted, [names[i] for i in present], config.confidence)
                frame = frame.join(scores[["score", "ci_low", "ci_high"]])
            frame.insert(0, "action", action)
            frames.append(frame.reset_index())
        columns = ["action", "source", "score", "ci_low", "ci_high", "n_participants", "n_judgements"]
        return pd.concat(frames, ignore_index=True).reindex(columns=columns)


def comparisons(rows: pd.DataFrame, names) -> pd.DataFrame:
    """Return one row per trial, as codes: ``left`` and ``right`` source (index into
    ``names``), ``left_stimulus``/``right_stimulus`` (ids), ``choice`` (index into ``CHOICES``)
    and the ``winner``/``loser`` source (-1 for ties), with ``pcode`` and ``action``.

    ``rows`` are sorted by trial and position with two clips per trial (as
    :meth:`Pairwise.answered` leaves them).
    """
    sources = pd.Categorical(rows["source"], categories=names).codes.astype(np.int64)
    stimuli = rows["stimulus"]
    choice = pd.Categorical(rows["choice"], categories=CHOICES).codes[0::2].astype(np.int64)
    left, right = sources[0::2], sources[1::2]
    frame = pd.DataFrame({
        "trial_key": rows["trial_key"].to_numpy()[0::2],
        "pcode": rows["pcode"].to_numpy()[0::2],
        "left": left,
        "right": right,
        "left_stimulus": stimuli.iloc[0::2].to_numpy(),
        "right_stimulus": stimuli.iloc[1::2].to_numpy(),
        "choice": choice,
        "winner": np.select([choice == 0, choice == 1], [left, right], -1),
        "loser": np.select([choice == 0, choice == 1], [right, left], -1),
    })
    if "action" in rows.columns:
        frame["action"] = rows["action"].to_numpy()[0::2]
    return frame


def sided_pairs(trials: pd.DataFrame, names, left_won=None) -> pd.DataFrame:
    """Return the comparisons ``trials`` (from :func:`comparisons`) as the pairs of
    :func:`analysis.mixed.worth`, the left clip first; ``left_won`` defaults to the
    answer "left"."""
    names = np.asarray(names, dtype=object)
    if left_won is None:
        left_won = (trials["choice"] == CHOICES.index("left")).to_numpy()
    return pd.DataFrame({
        "first": names[trials["left"].to_numpy()], "second": names[trials["right"].to_numpy()],
        "first_clip": trials["left_stimulus"].to_numpy(),
        "second_clip": trials["right_stimulus"].to_numpy(),
        "participant": trials["pcode"].to_numpy(), "trial": trials["trial_key"].to_numpy(),
        "won": np.asarray(left_won, dtype=float)})


def decided_trial_rows(rows: pd.DataFrame, trials: pd.DataFrame) -> pd.DataFrame:
    """Return the rows (two per trial, in trial order) of the decided comparisons."""
    keys = trials.loc[trials["winner"] >= 0, "trial_key"]
    return rows.loc[rows["trial_key"].isin(keys).to_numpy()]


def win_rates(trials: pd.DataFrame, design, names, config):
    """Return the per-pair table and the ``(K, K)`` matrix of row-over-column win rates.

    ``design`` is the crossed design of the decided trials (in their order); intervals
    and tests against 50 % treat participants and clips as random
    (:mod:`analysis.crossed`).
    """
    k = len(names)
    decided = trials.loc[trials["winner"] >= 0]
    wins = np.bincount(decided["winner"] * k + decided["loser"], minlength=k * k).reshape(k, k)
    tied = trials.loc[trials["winner"] < 0]
    pair = np.minimum(tied["left"], tied["right"]) * k + np.maximum(tied["left"], tied["right"])
    ties = {name: np.bincount(pair[tied["choice"] == CHOICES.index(name)], minlength=k * k).reshape(k, k)
            for name in ("both_good", "both_bad")}
    pairs = list(itertools.combinations(range(k), 2))
    index = {pair: i for i, pair in enumerate(pairs)}
    first = np.minimum(decided["winner"], decided["loser"]).to_numpy()
    second = np.maximum(decided["winner"], decided["loser"]).to_numpy()
    groups = np.array([index[(a, b)] for a, b in zip(first, second)], dtype=np.int64)
    won_first = (decided["winner"].to_numpy() == first).astype(float)
    result = crossed.bootstrap(design, crossed.ratio(won_first, groups, len(pairs)),
                               config)
    summary = result.summary(config.confidence, null=0.5, bounds=(0, 1))
    records = []
    for (a, b), row in zip(pairs, summary.itertuples()):
        won_a, won_b = int(wins[a, b]), int(wins[b, a])
        n = won_a + won_b
        records.append({
            "a": names[a], "b": names[b], "wins_a": won_a, "wins_b": won_b,
            "both_good": int(ties["both_good"][a, b]), "both_bad": int(ties["both_bad"][a, b]),
            "win_rate_a": won_a / n if n else np.nan, "ci_low": float(row.ci_low),
            "ci_high": float(row.ci_high), "p": float(row.p) if n else np.nan,
        })
    table = pd.DataFrame(records)
    if len(table):
        table["p_holm"] = stats.holm(table["p"])
    with np.errstate(invalid="ignore", divide="ignore"):
        matrix = pd.DataFrame(wins / (wins + wins.T), index=names, columns=names)
    return table, matrix


def bradley_terry(decided: pd.DataFrame, decided_rows: pd.DataFrame, names, config,
                  present=None) -> crossed.Crossed:
    """Return the crossed bootstrap of the Bradley-Terry log-worths of the decided
    comparisons ``decided`` (their rows ``decided_rows``, two per trial in the same order).

    ``present`` (source codes) restricts the fit to the sources a subset compared.
    """
    present = np.arange(len(names)) if present is None else np.asarray(present)
    recode = np.full(len(names), -1)
    recode[present] = np.arange(len(present))
    orders = np.stack([recode[decided["winner"]], recode[decided["loser"]]], axis=1)
    design = crossed.design(decided_rows, unit="trial_key")
    return crossed.bootstrap(design, crossed.worth_statistic(orders, len(present)),
                             config)


def position_bias(decided: pd.DataFrame, design, config) -> dict:
    """Return the share of decided comparisons won by the left clip, its interval over
    participants and clips and its t test against 0.5."""
    won_left = (decided["choice"] == CHOICES.index("left")).to_numpy(dtype=float)
    n = len(decided)
    result = crossed.bootstrap(design, crossed.ratio(won_left, np.zeros(n), 1),
                               config)
    row = result.summary(config.confidence, null=0.5, bounds=(0, 1)).iloc[0]
    return {"share_left": won_left.mean() if n else float("nan"), "ci_low": float(row["ci_low"]),
            "ci_high": float(row["ci_high"]), "left": int(won_left.sum()), "n_decided": n,
            "p": float(row["p"]), "n_participants": int(decided["pcode"].nunique())}


def _worth_plot(sources):
    def draw():
        from analysis.figures import interval_figure

        return interval_figure(sources, "Bradley-Terry log-worth", reference=0.0)

    return draw


def _matrix_plot(matrix):
    def draw():
        from analysis.figures import win_matrix_figure

        return win_matrix_figure(matrix)

    return draw


def comparisons_answered(rows, choices, table: str = "") -> tuple[pd.DataFrame, list[str]]:
    """Return the rows of answered comparisons (``choice`` one of ``choices``, as a
    categorical), each with exactly one left (position 0) and one right (position 1) clip,
    sorted by trial and position, and notes on what was left out. ``table`` names the kind
    of table in the error of an unknown choice."""
    notes = []
    choice = rows["choice"].astype("string").str.strip().str.lower()
    unknown = sorted(set(choice.dropna().unique()) - set(choices))
    if unknown:
        where = f" in a {table} table" if table else ""
        raise AnalysisError(f"unknown choice(s) {', '.join(unknown)}{where}; "
                            f"expected {', '.join(choices)}")
    if choice.isna().any():
        notes.append(f"{int(choice.isna().sum())} clip(s) of unanswered comparisons were left out")
    rows = rows.loc[choice.notna().to_numpy()].copy()
    rows["choice"] = pd.Categorical(choice.dropna(), categories=choices)
    rows["position"] = pd.to_numeric(rows["position"], errors="coerce")
    rows = rows.sort_values(["trial_key", "position"], kind="stable")
    shape = rows.groupby("trial_key")["position"].agg(["size", "min", "max"])
    good = shape.index[(shape["size"] == 2) & (shape["min"] == 0) & (shape["max"] == 1)]
    if len(good) < len(shape):
        notes.append(f"{len(shape) - len(good)} comparison(s) without exactly one left (position 0) "
                     f"and one right (position 1) clip were left out")
        rows = rows.loc[rows["trial_key"].isin(good)]
    return rows, notes
