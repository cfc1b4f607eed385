"""How many participants and judgements stand behind each number."""

from __future__ import annotations

import pandas as pd


def source_counts(rows: pd.DataFrame, by=("source",)) -> pd.DataFrame:
    """Return ``n_participants`` and ``n_judgements`` per group of ``by`` columns."""
    groups = rows.groupby(list(by), observed=True, sort=True)
    return pd.DataFrame({
        "n_participants": groups["pcode"].nunique(),
        "n_judgements": groups.size(),
    })


def ranked_sources(frame: pd.DataFrame, descending: bool = True) -> pd.DataFrame:
    """Return ``frame`` sorted by ``score`` (best first), ties broken by source name."""
    frame = frame.sort_index(kind="stable")
    return frame.sort_values("score", ascending=not descending, kind="stable")


def rank_columns(shares: pd.DataFrame) -> list[str]:
    """Return the ``rank_<r>`` columns of ``shares``, best rank first."""
    names = [c for c in shares.columns if str(c).startswith("rank_") and str(c)[5:].isdigit()]
    return sorted(names, key=lambda c: int(c[5:]))
