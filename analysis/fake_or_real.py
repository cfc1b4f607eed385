"""Fake or real: the share of each source's clips judged real (seed 000, Fig. 5).

Shares come with intervals over participants and clips (:mod:`analysis.crossed`). Each
generated source's rate is compared with the real clips' rate, itself an estimate from
its own clips, by the t test of their difference (Holm-corrected), and each
participant's sensitivity d' says how well they told real from generated (hit = a real
clip called real, false alarm = a generated one; its t test is over participants, for
these clips).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from analysis import crossed, mixed, simulate, stats
from analysis.counts import ranked_sources, source_counts
from analysis.formatting import number, p_text, plural
from analysis.registry import Analysis, Plot, StudyAnalysis, Table, register_analysis
from analysis.tables import as_boolean


@register_analysis("fake_or_real")
class FakeOrReal(StudyAnalysis):
    """Each clip is judged real or generated."""

    answer = "judged_real"
    mixed_model = "logistic"
    agreement_level = "nominal"
    design = "each clip was judged real or generated"

    def simulated_trials(self, rng, n_trials, n_sources, clips_per_trial):
        return rng.integers(0, n_sources, (n_trials, clips_per_trial))

    def simulated_answers(self, raters):
        """Judged real with probability sigmoid((q - middle) / noise + rater bias)."""
        bias = raters.rng.normal(0.0, 0.3, raters.participants)[raters.participant]
        chance = np.where(raters.random, 0.5,
                          simulate.sigmoid((raters.quality - raters.middle) / raters.noise + bias))
        return {"judged_real": pd.array(raters.rng.random(raters.n_rows) < chance,
                                        dtype="boolean")}

    def answered(self, rows):
        values = as_boolean(rows["judged_real"], "judged_real")
        notes = []
        if values.isna().any():
            notes.append(f"{int(values.isna().sum())} clip(s) without a real/generated answer were left out")
        rows = rows.loc[values.notna().to_numpy()].copy()
        rows["judged_real"] = values.dropna().to_numpy(dtype=bool)
        return rows, notes

    def judgement_values(self, rows):
        return pd.DataFrame({"participant": rows["pcode"].to_numpy(), "unit": rows["stimulus"].to_numpy(),
                             "value": rows["judged_real"].to_numpy(dtype=int)})

    def analyse(self, rows, config):
        names = sorted(rows["source"].unique())
        result, _ = crossed.group_means(rows, "judged_real", config)
        sources = judged_real_shares(rows, config, result)
        real = config.real_source
        tests, methods, notes = {"differences": None}, [], []
        methods.append(f"For each source{_per_action(rows)} we report the share of its clips "
                       f"judged real, and sources are compared by the mean over their clips of "
                       f"each clip's log-odds of being judged real (its empirical log-odds, 0.5 "
                       f"added to both counts; each clip weighed by its answers)")
        tables = []
        # Sources are compared on the log-odds scale of their clips (each clip's empirical
        # log-odds, averaged over the source's clips): where clips vary much a share is a
        # mean of clip rates piled near 0 and 1, and the t test of shares over 2 + 2 clips
        # rejected equal sources in 9 % of studies (docs/STATISTICS.md).
        log_odds = log_odds_bootstrap(rows, names, config)
        shown = crossed.report(log_odds, names, rows, config)
        tests["differences"] = shown.differences
        if real in sources.index:
            real_rate = sources.loc[real, "score"]
            generated = [s for s in names if s != real]
            contrast = np.zeros((len(generated), len(names)))
            for row, source in enumerate(generated):
                contrast[row, names.index(source)], contrast[row, names.index(real)] = 1.0, -1.0
            against = log_odds.contrast(contrast).summary(config.confidence)
            against.index = generated
            sources["difference"] = sources["score"] - real_rate
            sources.loc[generated, "log_odds_difference"] = against["estimate"]
            sources.loc[generated, "diff_ci_low"] = against["ci_low"]
            sources.loc[generated, "diff_ci_high"] = against["ci_high"]
            sources.loc[generated, "p"] = against["p"]
            sources.loc[generated, "p_holm"] = stats.holm(against["p"])
            sources.loc[generated, "share_clips"] = against["share_clips"]
            methods.append(
                f"each generated source was compared with the real clips (rate "
                f"{number(real_rate, 3)}) by the t test of the difference of their clips' mean "
                f"log-odds of being judged real (each clip's empirical log-odds, 0.5 added to "
                f"both counts) over participants and clips (the real clips' value is an estimate "
                f"too, from its own clips), Holm-corrected over the "
                f"{plural(len(generated), 'generated source')}"
            )
            notes += crossed.clip_warnings(
                against.assign(a=generated, b=real), shown.clips)
            per_participant, summary = sensitivity(rows, real, config.confidence)
            tests["dprime"] = summary
            tables.append(Table("dprime", "Sensitivity d' per participant (hit: real judged real; "
                                "false alarm: generated judged real; log-linear correction)",
                                per_participant))
            if summary["overall"]["n"]:
                overall = summary["overall"]
                methods.append(
                    f"each participant's sensitivity d' = z(H) - z(F) was computed with the "
                    f"log-linear correction (H: real clips judged real; F: generated clips judged "
                    f"real); mean d' = {number(overall['mean'], 2)} "
                    f"{_interval(overall)} over {plural(overall['n'], 'participant')}, t test against 0 over "
                    f"participants (for these clips): "
                    f"{p_text(overall['p'])}"
                )
            model_tables, model_methods, model_notes = mixed.logistic_tables(
                rows, "judged_real", real, config)
            tables += model_tables
            methods += model_methods
            notes += model_notes
            if model_tables:
                tests["mixed_model"] = model_tables[0].frame
            tables.append(Table("dprime_by_source", "Mean d' of real against each generated source "
                                "(t test against 0, Holm-corrected)",
                                pd.DataFrame(summary["by_source"])))
        else:
            notes.append(f"no source is called {real!r}: the tests against real clips and d' were "
                         f"skipped (set the real source's name)")
        notes += [note for note in shown.notes if "single clip" in note]
        methods.append(shown.method)
        columns = ["score", "ci_low", "ci_high", "judged_real", "difference", "log_odds_difference",
                   "diff_ci_low", "diff_ci_high", "p", "p_holm", "share_clips", "n_participants",
                   "n_judgements"]
        sources = ranked_sources(sources).reindex(columns=[c for c in columns if c in sources.columns])
        tables.insert(0, Table("sources", f"Share judged real with {config.confidence:.0%} intervals "
                               f"over participants and clips; difference from the real clips' "
                               f"rate, and the difference of the clips' mean log-odds of being "
                               f"judged real with its interval and t test (Holm)", sources))
        tables.insert(1, Table("differences", "Difference of the clips' mean log-odds of being "
                               "judged real a - b, t test over participants and clips (Holm), "
                               "and the shares of its variance",
                               shown.differences[crossed.DIFFERENCE_COLUMNS]))
        tables.append(Table("clips", "Clips per source, and per source and condition", shown.clips))
        if "action" in rows.columns and rows["action"].nunique() > 1:
            by_action = judged_real_shares(rows, config, by=("action", "source"))
            tables.append(Table("by_action", "Share judged real per action", by_action.reset_index()))
        plots = [Plot("judged_real", "Share of clips judged real", _plot(sources))]
        return Analysis(measure="share judged real", sources=sources, tables=tables, plots=plots,
                        methods=methods, notes=notes, tests=tests)


def log_odds_bootstrap(rows: pd.DataFrame, names, config) -> crossed.Crossed:
    """Return the crossed bootstrap of each source's mean log-odds of being judged real
    over its clips (:func:`analysis.crossed.clip_log_odds`), in the order of ``names``."""
    groups = pd.Categorical(rows["source"], categories=list(names)).codes
    statistic = crossed.clip_log_odds(rows["judged_real"].to_numpy(dtype=float),
                                      pd.factorize(rows["stimulus"])[0], groups, len(names))
    return crossed.bootstrap(crossed.design(rows), statistic, config)


def judged_real_shares(rows: pd.DataFrame, config, result=None, by=("source",)) -> pd.DataFrame:
    """Return ``score`` (share judged real), ``ci_low``/``ci_high`` over participants and
    clips (:func:`analysis.crossed.group_means`, or ``result`` when drawn) and counts per
    group of ``by``."""
    frame = source_counts(rows, by)
    frame["judged_real"] = rows.groupby(list(by), observed=True)["judged_real"].sum().astype(int)
    if result is None:
        result, index = crossed.group_means(rows, "judged_real", config, by)
    else:
        index = frame.index
    frame = frame.join(crossed.intervals(result, index, config, bounds=(0, 1)))
    return frame[["score", "ci_low", "ci_high", "judged_real", "n_participants", "n_judgements"]]


def sensitivity(rows: pd.DataFrame, real: str, confidence: float = 0.95) -> tuple[pd.DataFrame, dict]:
    """Return d' per participant and its summary (overall and per generated source).

    Participants who saw no real clip or no generated clip have no d' and are not counted.
    """
    is_real = (rows["source"] == real).to_numpy()
    frame = pd.DataFrame({
        "participant": rows["participant"].to_numpy(),
        "hits": rows["judged_real"].to_numpy() & is_real,
        "n_real": is_real,
        "false_alarms": rows["judged_real"].to_numpy() & ~is_real,
        "n_generated": ~is_real,
    }).groupby("participant", sort=True).sum()
    frame = frame.loc[(frame["n_real"] > 0) & (frame["n_generated"] > 0)].copy()
    frame["dprime"] = stats.dprime(frame["hits"], frame["n_real"], frame["false_alarms"],
                                   frame["n_generated"])
    summary = {"overall": stats.one_sample_t(frame["dprime"].to_numpy(), confidence), "by_source": []}
    for source in sorted(s for s in rows["source"].unique() if s != real):
        mine = rows.loc[(rows["source"] == source).to_numpy() | is_real]
        counts = pd.DataFrame({
            "participant": mine["participant"].to_numpy(),
            "hits": (mine["judged_real"] & (mine["source"] == real)).to_numpy(),
            "n_real": (mine["source"] == real).to_numpy(),
            "false_alarms": (mine["judged_real"] & (mine["source"] == source)).to_numpy(),
            "n_generated": (mine["source"] == source).to_numpy(),
        }).groupby("participant").sum()
        counts = counts.loc[(counts["n_real"] > 0) & (counts["n_generated"] > 0)]
        values = stats.dprime(counts["hits"], counts["n_real"], counts["false_alarms"], counts["n_generated"])
        result = stats.one_sample_t(np.asarray(values), confidence)
        summary["by_source"].append({"source": source, "mean_dprime": result["mean"],
                                     "ci_low": result["ci_low"], "ci_high": result["ci_high"],
                                     "t": result["t"], "p": result["p"], "n_participants": result["n"]})
    holm = stats.holm([row["p"] for row in summary["by_source"]])
    for row, adjusted in zip(summary["by_source"], holm):
        row["p_holm"] = float(adjusted)
    return frame.reset_index(), summary


def _interval(result) -> str:
    return f"[{number(result['ci_low'], 2)}, {number(result['ci_high'], 2)}]"


def _per_action(rows) -> str:
    return " (and each action)" if "action" in rows.columns and rows["action"].nunique() > 1 else ""


def _plot(sources):
    def draw():
        from analysis.figures import interval_figure

        return interval_figure(sources, "Share of clips judged real", bars=True, limits=(0, 1),
                               percent=True, reference=0.5)

    return draw
