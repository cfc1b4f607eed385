"""Publication figures drawn from analysis tables, rendered off-screen with Agg."""

from __future__ import annotations

from pathlib import Path

import matplotlib
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.ticker import PercentFormatter

from analysis.counts import rank_columns
from analysis.tables import AnalysisError

STYLE = {
    "font.size": 9,
    "axes.spines.top": False,
    "axes.spines.right": False,
    "axes.spines.left": False,
    "svg.fonttype": "none",  # keep text editable in the SVG
}
LABEL_THRESHOLD = 0.05


def plot_rank_shares(shares, path, *, svg: bool = False, title: str | None = None) -> list[Path]:
    """Draw ``shares`` (from ``rank_shares``) as stacked bars, as in seed 000, Fig. 4.

    Write a PNG at ``path`` (and an SVG beside it if ``svg``); return the paths written.
    See :func:`rank_shares_figure`.
    """
    return save_figure(rank_shares_figure(shares, title), path, svg=svg)


def rank_shares_figure(shares, title: str | None = None) -> Figure:
    """Return ``shares`` (from ``rank_shares``) drawn as stacked bars, as in seed 000, Fig. 4.

    One horizontal bar per source, in the table's order, top down; its segments are the
    shares of its judgements at rank 1..N, coloured from dark (best) to light (worst),
    labelled when at least 5 %.
    """
    if shares.index.nlevels > 1:
        raise AnalysisError("plot one action at a time: pass shares.xs(action)")
    ranks = rank_columns(shares)
    if shares.empty or not ranks:
        raise AnalysisError("nothing to plot: the table has no sources or no rank_<r> columns")
    values = shares[ranks].to_numpy(dtype=float)
    sources = [str(s) for s in shares.index]
    colours = matplotlib.colormaps["viridis"](np.linspace(0.0, 0.92, len(ranks)))

    with matplotlib.rc_context(STYLE):
        fig = Figure(figsize=(7.0, 1.3 + 0.42 * len(sources)), layout="constrained")
        FigureCanvasAgg(fig)
        ax = fig.add_subplot()
        rows = np.arange(len(sources))
        left = np.zeros(len(sources))
        for r, colour in enumerate(colours):
            share = values[:, r]
            ax.barh(
                rows, share, left=left, height=0.7, color=colour,
                label=_rank_label(r + 1, len(ranks)), edgecolor="white", linewidth=0.5,
            )
            text_colour = "white" if _luminance(colour) < 0.5 else "black"
            for row in np.flatnonzero(share >= LABEL_THRESHOLD):
                ax.text(
                    left[row] + share[row] / 2, row, f"{share[row]:.0%}",
                    ha="center", va="center", fontsize=7.5, color=text_colour,
                )
            left += share
        if "n_judgements" in shares.columns:
            for row, n in enumerate(shares["n_judgements"]):
                ax.text(1.01, row, f"n={int(n)}", va="center", fontsize=7.5, color="0.35")

        ax.set_yticks(rows, sources)
        ax.invert_yaxis()
        ax.tick_params(axis="y", length=0)
        ax.set_xlim(0, 1)
        ax.xaxis.set_major_formatter(PercentFormatter(1.0, decimals=0))
        ax.set_xlabel("Share of the source's clips placed at each rank")
        ax.legend(
            loc="lower center", bbox_to_anchor=(0.5, 1.0), ncol=min(len(ranks), 6),
            frameon=False, fontsize=7.5, handlelength=1.2, columnspacing=1.0,
        )
        ax.set_title(title or "Preference ranking", loc="left", pad=24 if len(ranks) <= 6 else 36)
        fig.text(0.0, 0.0, _caption(shares), ha="left", va="top", fontsize=7.5, color="0.35")
    return fig


def interval_figure(frame, label: str, *, title: str | None = None, reference: float | None = None,
                    bars: bool = False, limits=None, percent: bool = False) -> Figure:
    """Return one row per source of ``frame``: ``score`` with its ``ci_low``..``ci_high``.

    Sources run top down in the table's order (best first); ``n=`` labels come from
    ``n_judgements``. ``bars`` draws bars from the axis (shares, mean ratings) instead
    of points (worths); ``reference`` draws a dashed vertical line there.
    """
    if frame.empty:
        raise AnalysisError("nothing to plot: no sources")
    sources = [str(s) for s in frame.index]
    score = frame["score"].to_numpy(dtype=float)
    low = frame["ci_low"].to_numpy(dtype=float)
    high = frame["ci_high"].to_numpy(dtype=float)
    errors = np.vstack([score - low, high - score])
    # A percentile-bootstrap interval of a few judgements can miss its own point
    # estimate; the bar then stops at the estimate rather than pointing backwards.
    errors = np.clip(np.where(np.isfinite(errors), errors, 0.0), 0.0, None)
    rows = np.arange(len(sources))
    with matplotlib.rc_context(STYLE):
        fig = Figure(figsize=(6.0, 1.2 + 0.38 * len(sources)), layout="constrained")
        FigureCanvasAgg(fig)
        ax = fig.add_subplot()
        colour = matplotlib.colormaps["viridis"](0.35)
        if bars:
            ax.barh(rows, score, height=0.6, color=colour, alpha=0.85)
            ax.errorbar(score, rows, xerr=errors, fmt="none", ecolor="0.15", capsize=3, linewidth=1)
        else:
            ax.errorbar(score, rows, xerr=errors, fmt="o", color=colour, ecolor="0.3", capsize=3,
                        markersize=5, linewidth=1)
        if reference is not None:
            ax.axvline(reference, color="0.5", linestyle="--", linewidth=0.8)
        if limits is not None:
            ax.set_xlim(*limits)
        if percent:
            ax.xaxis.set_major_formatter(PercentFormatter(1.0, decimals=0))
        if "n_judgements" in frame.columns:
            for row, n in enumerate(frame["n_judgements"]):
                ax.text(1.01, row, f"n={int(n)}", va="center", fontsize=7.5, color="0.35",
                        transform=ax.get_yaxis_transform())
        ax.set_yticks(rows, sources)
        ax.invert_yaxis()
        ax.tick_params(axis="y", length=0)
        ax.set_xlabel(label)
        ax.grid(axis="x", color="0.9", linewidth=0.6)
        ax.set_axisbelow(True)
        if title:
            ax.set_title(title, loc="left")
        fig.text(0.0, 0.0, _caption(frame), ha="left", va="top", fontsize=7.5, color="0.35")
    return fig


def win_matrix_figure(matrix, *, title: str | None = None) -> Figure:
    """Return a heat map of ``matrix`` (row source's win rate against column source)."""
    names = [str(s) for s in matrix.index]
    values = matrix.to_numpy(dtype=float)
    with matplotlib.rc_context(STYLE):
        size = 1.6 + 0.55 * len(names)
        fig = Figure(figsize=(size + 1.0, size), layout="constrained")
        FigureCanvasAgg(fig)
        ax = fig.add_subplot()
        image = ax.imshow(values, cmap="RdBu", vmin=0, vmax=1)
        for (i, j), value in np.ndenumerate(values):
            if np.isfinite(value):
                colour = "white" if abs(value - 0.5) > 0.3 else "black"
                ax.text(j, i, f"{value:.0%}", ha="center", va="center", fontsize=7.5, color=colour)
        ax.set_xticks(range(len(names)), names, rotation=45, ha="right")
        ax.set_yticks(range(len(names)), names)
        ax.set_xlabel("against")
        ax.set_ylabel("source")
        fig.colorbar(image, ax=ax, format=PercentFormatter(1.0, decimals=0), shrink=0.8,
                     label="share of decided comparisons won")
        if title:
            ax.set_title(title, loc="left")
    return fig


def save_figure(fig: Figure, path, *, svg: bool = False) -> list[Path]:
    """Write ``fig`` as a PNG at ``path`` (and an SVG beside it if ``svg``); return the paths."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    written = [path]
    with matplotlib.rc_context(STYLE):
        fig.savefig(path, format="png", dpi=200, bbox_inches="tight")
        if svg:
            written.append(path.with_suffix(".svg"))
            fig.savefig(written[-1], format="svg", bbox_inches="tight")
    return written


def _caption(shares) -> str:
    # Totals travel in attrs; a table read back from CSV has only the per-source counts,
    # and in a ranking study every participant normally judges every source.
    participants = shares.attrs.get("n_participants")
    if participants is None and "n_participants" in shares.columns:
        participants = int(shares["n_participants"].max())
    judgements = shares.attrs.get("n_judgements")
    if judgements is None and "n_judgements" in shares.columns:
        judgements = int(shares["n_judgements"].sum())
    parts = []
    if participants is not None:
        parts.append(f"{participants} participants")
    if judgements is not None:
        parts.append(f"{judgements} judgements")
    return f"N = {', '.join(parts)}" if parts else ""


def _rank_label(rank: int, n_ranks: int) -> str:
    if rank == 1:
        return "Rank 1 (best)"
    return f"Rank {rank} (worst)" if rank == n_ranks else f"Rank {rank}"


def _luminance(colour) -> float:
    red, green, blue = colour[:3]
    return 0.2126 * red + 0.7152 * green + 0.0722 * blue
