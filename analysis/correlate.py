"""Does an objective metric order methods as people do? Rank correlations between a
study's human scores and the objective metrics of the same motions.

Two plain tables go in, one row per source (method):

- ``human``: ``score`` (the study's own analysis, higher = better), ``ci_low``, ``ci_high``;
- ``metrics``: one column per metric, the value measured on the motions the study showed.

Each metric has a direction (:data:`DIRECTIONS`): ``lower`` (FID, MMD: lower is better),
``higher`` (accuracy) or ``real`` (diversity, multimodality, APD: closer to the real
clips' value is better, as Action2Motion reads them). The correlations are between the
human score and the metric's *goodness* (the value, its negative, or minus its distance
to the real value), so +1 always means "the metric orders the sources exactly as people
did" and -1 "exactly the other way", whatever the metric's sign.

Intervals: bootstrap draw ``b`` pairs the human scores of one resample of participants
(:func:`human_draws`: participants drawn with replacement with all their judgements, the
study's analysis run again on them) with the metrics of one resample of each source's
motions (``metric_draws``: the metric protocol's repeats); the correlation of each draw
gives a percentile interval. Each correlation has a two-sided permutation p-value over
the sources (:func:`permutation_p`, exact up to 8): the methods are the units, so with 4
of them no p-value falls below 2 / 24 = 0.083, and the result says so plainly. Below
:data:`MIN_SOURCES` sources a rank correlation says next to nothing (with 3 sources, 1
in 6 random orders gives +1), and the result says so.

This module never imports :mod:`motion_metrics`: the caller computes the metrics and
passes them (and their directions) in.
"""

from __future__ import annotations

import html
import itertools
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import stats as scipy_stats

from analysis.figures import STYLE, save_figure
from analysis.formatting import display_frame, interval, number
from analysis.tables import AnalysisError

MIN_SOURCES = 4
# How each known metric is read: "lower" / "higher" is better, or "real": closer to the
# real clips' value is better. Unknown metrics count as "higher".
DIRECTIONS = {
    "fid": "lower", "mmd_avg": "lower", "mmd_seq": "lower", "dist_e": "lower",
    "accuracy": "higher", "mode_homogeneity": "higher",
    "diversity": "real", "multimodality": "real", "apd": "real", "n_apd": "real",
}
DIRECTION_TEXT = {"lower": "lower is better", "higher": "higher is better",
                  "real": "closer to real is better"}


def too_few_note(n_sources: int) -> str | None:
    """Return the warning for fewer than :data:`MIN_SOURCES` sources, or ``None``."""
    if n_sources >= MIN_SOURCES:
        return None
    return (f"only {n_sources} method(s): a rank correlation over fewer than {MIN_SOURCES} "
            f"sources means next to nothing (with 3, one random order in 6 gives +1; with 2 "
            f"it is always +1 or -1); compare at least {MIN_SOURCES} methods before reading "
            f"these numbers")


def goodness(values, direction: str, real=None) -> np.ndarray:
    """Return ``values`` turned so that higher is better (see the module docstring)."""
    values = np.asarray(values, dtype=float)
    if direction == "lower":
        return -values
    if direction == "higher":
        return values
    if direction == "real":
        if real is None or not np.isfinite(real):
            raise AnalysisError("a 'closer to real' metric needs the real clips' value")
        return -np.abs(values - float(real))
    raise AnalysisError(f"unknown direction {direction!r}; use lower, higher or real")


def rank_correlations(x, y) -> tuple[float, float]:
    """Return Spearman's rho and Kendall's tau-b of two equal-length vectors (NaN when
    undefined: fewer than 2 pairs, or a constant vector)."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    keep = np.isfinite(x) & np.isfinite(y)
    x, y = x[keep], y[keep]
    if len(x) < 2 or np.ptp(x) == 0 or np.ptp(y) == 0:
        return float("nan"), float("nan")
    rho = scipy_stats.spearmanr(x, y).statistic
    tau = scipy_stats.kendalltau(x, y).statistic
    return float(rho), float(tau)


# Up to this many permutations the permutation test enumerates them all (exact: 8! sources).
EXACT_PERMUTATIONS = 40_320


def permutation_p(x, y, seed: int = 0) -> tuple[float, float]:
    """Return two-sided permutation p-values of Spearman's rho and Kendall's tau-b over
    the pairs of ``x`` and ``y``: exact (every order of ``y`` against ``x``) up to 8
    sources, else from :data:`EXACT_PERMUTATIONS` random orders. The sources, not the
    judgements, are the units; NaN when a correlation is undefined."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    keep = np.isfinite(x) & np.isfinite(y)
    x, y = x[keep], y[keep]
    n = len(x)
    if n < 3 or np.ptp(x) == 0 or np.ptp(y) == 0:
        return float("nan"), float("nan")
    rx, ry = scipy_stats.rankdata(x), scipy_stats.rankdata(y)
    if math.factorial(n) <= EXACT_PERMUTATIONS:
        orders = np.array(list(itertools.permutations(range(n))))
    else:
        rng = np.random.default_rng(seed)
        orders = np.argsort(rng.random((EXACT_PERMUTATIONS, n)), axis=1)
    permuted = ry[orders]  # (R, n): y's ranks in every order, the identity among them
    cx = rx - rx.mean()
    cy = permuted - permuted.mean(axis=1, keepdims=True)
    rho = cy @ cx / np.sqrt((cx ** 2).sum() * (cy ** 2).sum(axis=1))
    upper = np.triu_indices(n, 1)
    sx = np.sign(x[:, None] - x[None, :])[upper]
    values = y[orders]
    sy = np.sign(values[:, :, None] - values[:, None, :])[:, upper[0], upper[1]]
    tau = sy @ sx / np.sqrt(np.abs(sx).sum() * np.abs(sy).sum(axis=1))
    observed_rho = scipy_stats.spearmanr(x, y).statistic
    observed_tau = scipy_stats.kendalltau(x, y).statistic
    tolerance = 1e-12
    p_rho = float(np.mean(np.abs(rho) >= abs(observed_rho) - tolerance))
    p_tau = float(np.mean(np.abs(tau) >= abs(observed_tau) - tolerance))
    return p_rho, p_tau


def smallest_p(n_sources: int) -> float:
    """Return the smallest two-sided permutation p-value ``n_sources`` can give (2 / n!)."""
    return 2.0 / float(np.prod(np.arange(1, n_sources + 1))) if n_sources > 1 else 1.0


@dataclass
class Correlation:
    """What :func:`correlate` returns: the table, per-source values and notes."""

    table: pd.DataFrame  # one row per metric
    sources: pd.DataFrame  # one row per source: human score and interval, each metric
    directions: dict
    real: dict  # the real clips' value of each metric (None when it has none)
    notes: list[str] = field(default_factory=list)
    n_bootstrap: int = 0
    confidence: float = 0.95
    human_measure: str = "human score"

    @property
    def too_few(self) -> bool:
        return len(self.sources) < MIN_SOURCES


def correlate(human: pd.DataFrame, metrics: pd.DataFrame, *, directions: dict | None = None,
              real: dict | None = None, human_draws: pd.DataFrame | None = None,
              metric_draws: dict | None = None, confidence: float = 0.95,
              human_measure: str = "human score") -> Correlation:
    """Correlate ``human["score"]`` with each column of ``metrics`` over their common sources.

    ``directions`` maps metric -> ``lower``/``higher``/``real`` (default
    :data:`DIRECTIONS`); ``real`` maps a metric to the real clips' value (needed by
    ``real`` metrics). ``human_draws`` is ``(B, sources)`` (bootstrap draws of the human
    score, :func:`human_draws`); ``metric_draws`` maps metric -> ``(B, sources)`` frame of
    the same B draws of the metric. With both, every correlation gets a percentile
    interval; rows of a draw with a missing value count as missing.
    """
    if "score" not in human.columns:
        raise AnalysisError(f"the human table needs a 'score' column; it has {', '.join(human.columns)}")
    directions = {**DIRECTIONS, **(directions or {})}
    real = dict(real or {})
    human = human.copy()
    human.index = human.index.astype(str)
    metrics = metrics.copy()
    metrics.index = metrics.index.astype(str)
    sources = [s for s in human.index if s in set(metrics.index)]
    if not sources:
        raise AnalysisError(
            f"no source has both a human score and metrics (human: {', '.join(human.index)}; "
            f"metrics: {', '.join(metrics.index)})")
    notes = []
    dropped = sorted(set(human.index) ^ set(metrics.index))
    if dropped:
        notes.append(f"left out (a human score or metrics missing): {', '.join(dropped)}")
    few = too_few_note(len(sources))
    if few:
        notes.append(few)
    elif smallest_p(len(sources)) > 0.05:
        notes.append(f"with {len(sources)} methods no ordering can reach p < 0.05 (the smallest "
                     f"permutation p-value is {smallest_p(len(sources)):.3f}): nothing can be "
                     f"concluded about whether the metrics order methods as people do")
    score = human.loc[sources, "score"].to_numpy(float)
    rows = []
    for name in metrics.columns:
        direction = directions.get(name, "higher")
        values = metrics.loc[sources, name].to_numpy(float)
        row = {"metric": name, "direction": DIRECTION_TEXT.get(direction, direction),
               "real": real.get(name, np.nan), "n_sources": int(np.isfinite(values).sum())}
        if direction == "real" and (real.get(name) is None or not np.isfinite(real.get(name))):
            notes.append(f"{name}: no real value to compare with; not correlated")
            rows.append({**row, **_empty()})
            continue
        good = goodness(values, direction, real.get(name))
        rho, tau = rank_correlations(score, good)
        rho_p, tau_p = permutation_p(score, good)
        row.update({"spearman": rho, "spearman_low": np.nan, "spearman_high": np.nan,
                    "spearman_p": rho_p, "kendall": tau, "kendall_low": np.nan,
                    "kendall_high": np.nan, "kendall_p": tau_p})
        if human_draws is not None and metric_draws is not None and name in metric_draws:
            h = human_draws.reindex(columns=sources).to_numpy(float)
            m = metric_draws[name].reindex(columns=sources).to_numpy(float)
            count = min(len(h), len(m))
            draws = np.array([rank_correlations(h[b], goodness(m[b], direction, real.get(name)))
                              for b in range(count)]).reshape(-1, 2)
            for k, key in enumerate(("spearman", "kendall")):
                low, high = _percentiles(draws[:, k], confidence)
                row[f"{key}_low"], row[f"{key}_high"] = low, high
        rows.append(row)
    table = pd.DataFrame(rows, columns=["metric", "direction", "real", "n_sources",
                                       *_empty()])
    per_source = human.loc[sources, [c for c in ("score", "ci_low", "ci_high") if c in human.columns]]
    per_source = per_source.join(metrics.loc[sources])
    per_source.index.name = "source"
    return Correlation(table, per_source, {n: directions.get(n, "higher") for n in metrics.columns},
                       {n: real.get(n) for n in metrics.columns}, notes,
                       0 if human_draws is None else len(human_draws), confidence, human_measure)


def _empty() -> dict:
    return {key: np.nan for key in ("spearman", "spearman_low", "spearman_high", "spearman_p",
                                    "kendall", "kendall_low", "kendall_high", "kendall_p")}


def _percentiles(values: np.ndarray, confidence: float) -> tuple[float, float]:
    values = values[np.isfinite(values)]
    if len(values) == 0:
        return float("nan"), float("nan")
    tail = 100 * (1 - confidence) / 2
    return float(np.percentile(values, tail)), float(np.percentile(values, 100 - tail))


# --- the human side -----------------------------------------------------------------


def resample_participants(table: pd.DataFrame, rng: np.random.Generator) -> pd.DataFrame:
    """Return ``table`` with its participants drawn with replacement, all their rows kept;
    a participant drawn twice becomes two participants (and two sets of trials)."""
    people = pd.unique(table["participant"].astype(str))
    chosen = rng.choice(len(people), size=len(people), replace=True)
    groups = {p: rows for p, rows in table.groupby(table["participant"].astype(str), sort=False)}
    parts = []
    for copy, index in enumerate(chosen):
        rows = groups[people[index]].copy()
        rows["participant"] = rows["participant"].astype(str) + f"~{copy}"
        for column in ("trial_id", "trial"):
            if column in rows.columns and rows[column].notna().all():
                rows[column] = rows[column].astype(str) + f"~{copy}"
        parts.append(rows)
    return pd.concat(parts, ignore_index=True)


def human_draws(table: pd.DataFrame, score_of, n: int, seed: int = 0) -> pd.DataFrame:
    """Return ``(n, sources)`` human scores, one row per resample of participants.

    ``score_of(table) -> Series`` (per source) is the study's analysis, run again on each
    resample (without its own bootstrap); a resample it cannot analyse (e.g. every
    participant drawn saw one source only) is a row of NaN, counted in
    ``frame.attrs["failed"]``.
    """
    rng = np.random.default_rng(seed)
    rows, failed = [], 0
    for _ in range(int(n)):
        try:
            rows.append(score_of(resample_participants(table, rng)))
        except (ValueError, np.linalg.LinAlgError):  # AnalysisError is a ValueError
            rows.append(pd.Series(dtype=float))
            failed += 1
    frame = pd.DataFrame(rows).reset_index(drop=True)
    frame.columns = frame.columns.astype(str)
    frame.attrs["failed"] = failed
    return frame


# --- the report ---------------------------------------------------------------------


def scatter_figure(result: Correlation, metric: str):
    """Return a scatter of the human score (with its interval) against ``metric``, one
    labelled point per source."""
    import matplotlib
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    frame = result.sources
    x = frame[metric].to_numpy(float)
    y = frame["score"].to_numpy(float)
    row = result.table.set_index("metric").loc[metric]
    with matplotlib.rc_context(STYLE):
        fig = Figure(figsize=(4.6, 3.6), layout="constrained")
        FigureCanvasAgg(fig)
        ax = fig.add_subplot()
        colour = matplotlib.colormaps["viridis"](0.35)
        if {"ci_low", "ci_high"} <= set(frame.columns):
            errors = np.vstack([y - frame["ci_low"].to_numpy(float),
                                frame["ci_high"].to_numpy(float) - y])
            errors = np.clip(np.where(np.isfinite(errors), errors, 0.0), 0.0, None)
            ax.errorbar(x, y, yerr=errors, fmt="o", color=colour, ecolor="0.3", capsize=3,
                        markersize=5, linewidth=1)
        else:
            ax.plot(x, y, "o", color=colour, markersize=5)
        for source, xi, yi in zip(frame.index, x, y):
            ax.annotate(str(source), (xi, yi), xytext=(4, 4), textcoords="offset points",
                        fontsize=7.5, color="0.25")
        real = result.real.get(metric)
        caption = f"N = {len(frame)} sources" + (" (too few to mean much)" if result.too_few else "")
        if result.directions.get(metric) == "real" and real is not None and np.isfinite(real):
            ax.axvline(real, color="0.5", linestyle="--", linewidth=0.8)
            caption += "; dashed line: the real clips' value"
        ax.set_xlabel(f"{metric} ({DIRECTION_TEXT.get(result.directions.get(metric), '')})")
        ax.set_ylabel(result.human_measure)
        ax.grid(color="0.9", linewidth=0.6)
        ax.set_axisbelow(True)
        ax.set_title(f"{metric}: Spearman {number(row['spearman'], 2)}, Kendall "
                     f"{number(row['kendall'], 2)}", loc="left")
        fig.text(0.0, 0.0, caption, ha="left", va="top", fontsize=7.5, color="0.35")
    return fig


def write_correlation_report(result: Correlation, out, title: str = "Human scores and "
                             "objective metrics", details: list[str] | None = None) -> list[Path]:
    """Write ``correlations.csv|.md|.tex``, ``sources.csv|.md|.tex``, one scatter per
    metric (``scatter_<metric>.png|.svg``) and ``report.html`` under ``out``; return the paths."""
    from analysis.report import PAGE, png_base64, write_table

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    written = write_table(result.table, out / "correlations",
                          "Rank correlations of the human score with each metric's goodness")
    written += write_table(result.sources, out / "sources", "Human score and metrics per source")
    esc = html.escape
    body = [f"<h1>{esc(title)}</h1>",
            f"<p class='lead'>{len(result.sources)} sources. Human score: "
            f"{esc(result.human_measure)}. A correlation of +1 means the metric orders the "
            f"sources exactly as the participants did, -1 exactly the other way (each "
            f"metric is turned so that higher is better first).</p>"]
    if result.too_few:
        warning = esc(too_few_note(len(result.sources)))
        body.append(f"<p class='warning'><b>Too few sources.</b> {warning}.</p>")
    body.append("<h2>Correlations</h2><ul>")
    for row in result.table.itertuples():
        body.append(
            f"<li><b>{esc(row.metric)}</b> ({esc(row.direction)}): Spearman "
            f"{number(row.spearman, 2)} {interval(row.spearman_low, row.spearman_high, 2)}, "
            f"Kendall {number(row.kendall, 2)} {interval(row.kendall_low, row.kendall_high, 2)}</li>")
    body.append("</ul>")
    method = (f"Intervals: {result.confidence:.0%} percentile intervals of {result.n_bootstrap} "
              f"bootstrap draws, each pairing the human scores of one resample of participants "
              f"(with all their judgements, the study's analysis run again) with the metrics of "
              f"one resample of each source's motions. With few sources a rank correlation takes few "
              f"values, so a percentile interval can lie beside its own point estimate: read "
              f"it as the spread of the draws."
              if result.n_bootstrap else "No intervals (the bootstrap was switched off).")
    body.append(f"<h2>Methods</h2><p class='methods'>{esc(method)}"
                + "".join(f" {esc(d)}" for d in details or []) + "</p>")
    if result.notes:
        body.append("<h2>Notes</h2><ul>" + "".join(f"<li>{esc(n)}</li>" for n in result.notes)
                    + "</ul>")
    body.append("<h2>Figures</h2>")
    for metric in result.table["metric"]:
        if not np.isfinite(result.sources[metric].to_numpy(float)).any():
            continue
        fig = scatter_figure(result, metric)
        name = f"scatter_{metric}"
        written += save_figure(fig, out / f"{name}.png", svg=True)
        body.append(f"<figure><img alt='{esc(metric)}' src='data:image/png;base64,"
                    f"{png_base64(fig)}'><figcaption>Human score against {esc(metric)} "
                    f"(<a href='{name}.svg'>SVG</a>, <a href='{name}.png'>PNG</a>)"
                    f"</figcaption></figure>")
    body.append("<h2>Tables</h2>")
    for frame, name, caption in ((result.table, "correlations", "Correlations"),
                                 (result.sources, "sources", "Per source")):
        body.append(f"<h3 id='{name}'>{caption}</h3>")
        body.append(display_frame(frame).to_html(index=False, escape=True, border=0, classes="data"))
        body.append(f"<p class='files'>{name}.csv, .md, .tex</p>")
    page = out / "report.html"
    page.write_text(PAGE.format(title=esc(title), body="\n".join(body)))
    written.append(page)
    return written
