"""Preference ranking: the share of each source's clips at each rank, and its worth.

The shares are the statistic behind seed 000, Fig. 4 ("64 % of A2M motions in the top
2"). The study analysis adds intervals to the shares and Plackett-Luce worths, and tests of the
worths' differences, all over participants and clips (:mod:`analysis.crossed`), Kendall's W
(with Friedman's test, for these clips) as participants' concordance, and the same per
action.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy import sparse

from analysis import crossed, mixed, simulate, stats
from analysis.counts import rank_columns, ranked_sources, source_counts
from analysis.formatting import number, p_text
from analysis.registry import Analysis, Plot, StudyAnalysis, Table, register_analysis
from analysis.tables import AnalysisError, ranked_judgements

SUMMARY_COLUMNS = ("n_judgements", "n_participants", "mean_rank")


def rank_shares(table: pd.DataFrame, by_action: bool = False) -> pd.DataFrame:
    """Return, per source, the share of its judgements at each rank 1..N.

    ``table`` is a response table (:mod:`analysis.tables`); rows without a rank are
    ignored. N is the largest number of clips in any trial.

    Rows are indexed by ``source`` (by ``action, source`` when ``by_action``) and ordered
    by mean rank, best first. Columns: ``rank_1..rank_N`` (fractions summing to 1 per
    row), ``n_judgements``, ``n_participants``, ``mean_rank``. ``attrs`` holds the
    totals ``n_participants`` and ``n_judgements``, ``n_items`` (the trial sizes seen) and
    ``notes``, caveats to report with the numbers.
    """
    columns = ("participant", "source", "rank", "n_items") + (("action",) if by_action else ())
    rows = ranked_judgements(table, columns)
    if rows.empty:
        raise AnalysisError("the table has no ranked judgements")
    n_ranks = int(rows["n_items"].max())
    if by_action:
        shares = pd.concat(
            {action: _shares(group, n_ranks) for action, group in rows.groupby("action")},
            names=["action"],
        )
    else:
        shares = _shares(rows, n_ranks)
    sizes = sorted(int(n) for n in rows["n_items"].unique())
    shares.attrs = {
        "n_participants": int(rows["participant"].nunique()),
        "n_judgements": len(rows),
        "n_items": sizes,
        "notes": _notes(rows, sizes),
    }
    return shares


def top_share(shares: pd.DataFrame, k: int = 2) -> pd.Series:
    """Return, per row of ``shares``, the share of judgements in ranks 1..k."""
    columns = [f"rank_{r}" for r in range(1, k + 1) if f"rank_{r}" in shares.columns]
    return shares[columns].sum(axis=1)


def _shares(rows: pd.DataFrame, n_ranks: int) -> pd.DataFrame:
    counts = rows.groupby(["source", "rank"], observed=True).size().unstack("rank", fill_value=0)
    counts = counts.reindex(columns=range(1, n_ranks + 1), fill_value=0)
    by_source = rows.groupby("source")
    summary = pd.DataFrame(
        {
            "n_judgements": by_source.size(),
            "n_participants": by_source["participant"].nunique(),
            "mean_rank": by_source["rank"].mean(),
        }
    )
    shares = counts.div(summary["n_judgements"], axis=0)
    shares.columns = [f"rank_{r}" for r in shares.columns]
    shares = shares.join(summary)
    shares.index.name = "source"
    shares.columns.name = None
    # Stable sort: sources with equal mean rank stay in alphabetical order.
    return shares.sort_values("mean_rank", kind="stable")


def _notes(rows: pd.DataFrame, sizes: list[int]) -> list[str]:
    notes = []
    if len(sizes) > 1:
        notes.append(
            f"trials show {sizes[0]} to {sizes[-1]} clips; ranks run 1..{sizes[-1]}, so clips "
            f"from smaller trials cannot take the lowest ranks"
        )
    sources = sorted(rows["source"].unique())
    if len(sources) == 1:
        notes.append(f"only one source ({sources[0]}): the rank shares compare nothing")
    return notes


@register_analysis("ranking")
class Ranking(StudyAnalysis):
    """Each trial shows one action's clips; the participant ranks them, 1 = best."""

    answer = "rank"
    mixed_model = "worth"
    agreement_level = "ordinal"
    design = ("each trial showed clips of one action from the sources in random order, "
              "and participants ranked them from best (1) to worst")

    def simulated_trials(self, rng, n_trials, n_sources, clips_per_trial):
        return simulate.every_source(n_trials, n_sources)

    def simulated_answers(self, raters):
        """Rank by quality + Gumbel noise (a Plackett-Luce draw)."""
        utility = (np.where(raters.random, 0.0, raters.quality)
                   + raters.noise * raters.rng.gumbel(size=raters.n_rows))
        utility = utility.reshape(-1, raters.m)
        ranks = np.empty_like(utility, dtype=np.int64)
        np.put_along_axis(ranks, np.argsort(-utility, axis=1), np.arange(1, raters.m + 1)[None],
                          axis=1)
        return {"rank": pd.array(ranks.ravel(), dtype="Int64")}

    choice_depth = None

    def worth_choices(self, rows):
        """Return a ranking's Luce choices: rank 1 among all the trial's sources, rank 2
        among the rest, and so on (Plackett-Luce); ``rows`` as :meth:`answered` leaves them.
        Each choice also names the clips it was among (``among_clips``, aligned with
        ``among``) and its participant."""
        chosen, among, among_clips, participant = [], [], [], []
        named = {"stimulus", "pcode"} <= set(rows.columns)
        for _, trial in rows.sort_values(["trial_key", "rank"], kind="stable").groupby(
                "trial_key", sort=False):
            order = tuple(trial["source"])
            clips = tuple(trial["stimulus"]) if named else ()
            for place in range(len(order) - 1):
                chosen.append(order[place])
                among.append(order[place:])
                if named:
                    among_clips.append(clips[place:])
                    participant.append(trial["pcode"].iloc[0])
        choices = pd.DataFrame({"chosen": chosen, "among": pd.Series(among, dtype=object),
                                "weight": 1.0})
        if named:
            choices["among_clips"] = pd.Series(among_clips, dtype=object)
            choices["participant"] = participant
        return choices

    def answered(self, rows):
        """Return ranked rows sorted by trial and rank, ranks renumbered 1..m within the trial.

        Renumbering closes the gaps that leaving out catch clips or unranked clips
        opens; ``n_items`` becomes the number of ranked clips of the trial.
        """
        notes = []
        ranks = pd.to_numeric(rows["rank"], errors="coerce")
        unanswered = int(ranks.isna().sum())
        if unanswered:
            notes.append(f"{unanswered} clip(s) without a rank were left out")
        bad = ranks.notna() & ((ranks % 1 != 0) | (ranks < 1))
        if bad.any():
            raise AnalysisError(f"{int(bad.sum())} row(s) have a rank that is not a whole number "
                                f"of 1 or more, e.g. {ranks[bad].iloc[0]!r}")
        rows = rows.loc[ranks.notna()]
        ranks = ranks[ranks.notna()].to_numpy(dtype=np.int64)
        keys = rows["trial_key"].to_numpy()
        order = np.lexsort((ranks, keys))
        keys, ranks = keys[order], ranks[order]
        tied = (keys[1:] == keys[:-1]) & (ranks[1:] == ranks[:-1])
        if tied.any():
            raise AnalysisError(f"{int(pd.unique(keys[1:][tied]).size)} trial(s) give two clips the "
                                f"same rank; ranks within a trial must differ")
        starts = np.flatnonzero(np.r_[True, keys[1:] != keys[:-1]])
        sizes = np.diff(np.r_[starts, len(keys)])
        place = np.arange(len(keys)) - np.repeat(starts, sizes) + 1
        rows = rows.iloc[order].copy()
        rows["rank"] = place
        rows["n_items"] = np.repeat(sizes, sizes)
        return rows, notes

    def analyse(self, rows, config):
        slim = rows[["pcode", "source", "rank", "n_items"] + (["action"] if "action" in rows else [])]
        slim = slim.rename(columns={"pcode": "participant"})
        shares = rank_shares(slim)
        names = sorted(rows["source"].unique())
        fitted = plackett_luce(rows, names, config)
        shown = crossed.report(fitted, names, rows, config)
        sources = source_counts(rows).join(shown.scores[["score", "ci_low", "ci_high"]])
        sources["mean_rank"] = rows.groupby("source")["rank"].mean()
        sources["top_1"] = shares["rank_1"]
        sources["top_2"] = top_share(shares, 2)
        sources = ranked_sources(sources)[["score", "ci_low", "ci_high", "mean_rank", "top_1",
                                           "top_2", "n_participants", "n_judgements"]]
        shares = shares.loc[sources.index]
        intervals = share_intervals(shares, config, rows)

        tables = [
            Table("sources", "Plackett-Luce worth (log scale, 0 = average source) with "
                  f"{config.confidence:.0%} intervals over participants and clips, mean rank and "
                  f"top-k shares", sources),
            Table("differences", "Difference of Plackett-Luce worths a - b, t test over "
                  "participants and clips (Holm), and the shares of its variance from "
                  "participants, clips and single answers",
                  shown.differences[crossed.DIFFERENCE_COLUMNS]),
            Table("rank_shares", "Share of each source's judgements at each rank (as seed 000, Fig. 4)",
                  shares),
            Table("rank_share_intervals", f"Rank shares with {config.confidence:.0%} intervals over "
                  f"participants and clips",
                  intervals),
            Table("clips", "Clips per source, and per source and condition", shown.clips),
        ]
        tests, methods, notes = {"differences": shown.differences}, [], list(shown.notes)
        means = rows.groupby(["pcode", "source"])["rank"].mean().unstack("source")[names]
        complete = means.dropna()
        if len(complete) >= 2:
            result = stats.friedman(complete.to_numpy())
            tests["friedman"] = {k: v for k, v in result.items() if k != "mean_ranks"}
            tests["kendall_w"] = result["kendall_w"]
            methods.append(
                f"Kendall's W = {number(result['kendall_w'], 3)} measures how far participants' "
                f"orderings agree (Friedman's test on each participant's mean rank per source, "
                f"{len(complete)} participants who ranked every source: chi2({result['df']}) = "
                f"{number(result['statistic'], 2)}, {p_text(result['p'])}; it holds these clips "
                f"fixed, so it says participants agree about them, not that the sources differ: "
                f"the differences of worths are the test of that)"
            )
        if len(complete) < len(means):
            notes.append(f"{len(means) - len(complete)} participant(s) did not rank every source "
                         f"and are left out of Friedman's test")
        methods.insert(0, (
            f"For each source we report the share of its judgements at each rank and a "
            f"Plackett-Luce worth fitted to the rankings (log scale, centred on 0; a weak prior of "
            f"one virtual win and one virtual loss per source against a reference keeps estimates "
            f"finite), refitted in every bootstrap resample; sources were compared by the "
            f"differences of their worths"
        ))
        methods.insert(1, shown.method)
        if "action" in rows.columns and rows["action"].nunique() > 1:
            tables.append(Table("by_action", "Plackett-Luce worth and mean rank per action",
                                self._by_action(rows, config)))
            tables.append(Table("rank_shares_by_action", "Rank shares per action",
                                rank_shares(slim, by_action=True)))
        model_tables, model_methods, model_notes, model = mixed.worth_tables(
            mixed.ranked_pairs(rows, "rank"), names, config, sources["score"],
            measure="Plackett-Luce worth",
            reading="every two clips of a ranking, the higher ranked one preferred: under "
                    "Plackett-Luce each such pair follows Bradley-Terry with the same worths",
            clustered=True, checkpoints=mixed.clip_checkpoints(rows))
        tables += model_tables
        methods += model_methods
        notes += model_notes
        if model:
            tests["mixed_model"] = model["differences"]
        plots = [
            Plot("rank_shares", "Share of each source's clips at each rank", _rank_plot(shares)),
            Plot("worth", "Plackett-Luce worth", _worth_plot(sources, "Plackett-Luce log-worth")),
        ]
        return Analysis(
            measure="Plackett-Luce worth (log scale)", sources=sources, tables=tables, plots=plots,
            methods=methods, notes=notes, tests=tests,
        )

    def _by_action(self, rows, config) -> pd.DataFrame:
        frames = []
        for action, group in rows.groupby("action", sort=True):
            present = sorted(group["source"].unique())
            counts = source_counts(group)
            counts["mean_rank"] = group.groupby("source")["rank"].mean()
            frame = counts
            if len(present) > 1:
                fitted = crossed.scores(plackett_luce(group, present, config), present,
                                        config.confidence)
                frame = counts.join(fitted[["score", "ci_low", "ci_high"]])
            frame.insert(0, "action", action)
            frames.append(frame.reset_index())
        columns = ["action", "source", "score", "ci_low", "ci_high", "mean_rank", "n_participants",
                   "n_judgements"]
        return pd.concat(frames, ignore_index=True).reindex(columns=columns)


def plackett_luce(rows: pd.DataFrame, names, config) -> crossed.Crossed:
    """Return the crossed bootstrap of the Plackett-Luce log-worths per source of ranked
    ``rows`` (sorted by trial and rank, as :meth:`Ranking.answered` leaves them); each
    trial is a unit, weighed by its participant's and all its clips' draws."""
    orders, _ = _orders(rows, names)
    return crossed.bootstrap(crossed.design(rows, unit="trial_key"),
                             crossed.worth_statistic(orders, len(names)),
                             config)


def share_intervals(shares: pd.DataFrame, config, rows: pd.DataFrame) -> pd.DataFrame:
    """Return one row per source and rank: ``share``, ``ci_low``/``ci_high``, counts.

    Intervals treat participants and clips as random (:mod:`analysis.crossed`; each
    judgement a unit, weighed by its participant's and its clip's draws).
    """
    ranks = rank_columns(shares)
    n = shares["n_judgements"].to_numpy(dtype=float)[:, None]
    counts = np.rint(shares[ranks].to_numpy(dtype=float) * n)
    n_sources, n_ranks = len(shares), len(ranks)
    source = shares.index.get_indexer(rows["source"])
    rank = rows["rank"].to_numpy()
    n_rows = len(rows)
    # One statistic for every (source, rank) share: judgements at the rank over the source's.
    at_rank = sparse.csr_matrix((np.ones(n_rows), (np.arange(n_rows), source * n_ranks + rank - 1)),
                                shape=(n_rows, n_sources * n_ranks))
    of_source = sparse.csr_matrix((np.ones(n_rows), (np.arange(n_rows), source)),
                                  shape=(n_rows, n_sources))

    width = n_sources * n_ranks

    def finish(sums):
        with np.errstate(invalid="ignore", divide="ignore"):
            return sums[:, :width] / np.repeat(sums[:, width:], n_ranks, axis=1)

    statistic = crossed.Linear(sparse.hstack([at_rank, of_source]), finish)
    result = crossed.bootstrap(crossed.design(rows), statistic, config)
    summary = result.summary(config.confidence, bounds=(0, 1))
    low = summary["ci_low"].to_numpy().reshape(n_sources, n_ranks)
    high = summary["ci_high"].to_numpy().reshape(n_sources, n_ranks)
    frame = pd.DataFrame({
        "source": np.repeat(shares.index.to_numpy(), len(ranks)),
        "rank": np.tile([int(r[5:]) for r in ranks], len(shares)),
        "share": (counts / n).ravel(),
        "ci_low": low.ravel(),
        "ci_high": high.ravel(),
        "count": counts.ravel().astype(int),
        "n_judgements": np.repeat(shares["n_judgements"].to_numpy(dtype=int), len(ranks)),
    })
    return frame


def _orders(rows, names):
    """Return ``(T, m)`` source codes best first (``-1`` padded) and each trial's participant."""
    codes = pd.Categorical(rows["source"], categories=names).codes.astype(np.int64)
    keys = rows["trial_key"].to_numpy()
    starts = np.flatnonzero(np.r_[True, keys[1:] != keys[:-1]])
    sizes = np.diff(np.r_[starts, len(keys)])
    orders = np.full((len(starts), int(sizes.max())), -1, dtype=np.int64)
    trial = np.repeat(np.arange(len(starts)), sizes)
    orders[trial, rows["rank"].to_numpy() - 1] = codes
    return orders, rows["pcode"].to_numpy()[starts]


def _rank_plot(shares):
    def draw():
        from analysis.figures import rank_shares_figure

        return rank_shares_figure(shares)

    return draw


def _worth_plot(sources, label):
    def draw():
        from analysis.figures import interval_figure

        return interval_figure(sources, label, reference=0.0)

    return draw
