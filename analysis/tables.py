"""The response table: one row per judgement, its columns, validation and file I/O.

A judgement is one clip of one trial with its answer, in the column its study type's
analysis names (:attr:`analysis.registry.StudyAnalysis.answer`):

- ``rank``: 1 = best, among the ``n_items`` clips of the trial;
- ``rating``: 1..5, higher = more realistic;
- ``judged_real``: whether the participant called the clip real;
- ``choice``: the trial's answer on the rows of its clips (``position`` 0 is the left
  clip, 1 the right), in the words of the type's analysis module.

These four are in every table (empty where a type does not use them). A type that needs
columns of its own declares them (``StudyAnalysis.extra_columns``) and the export adds
them after the shared ones; the type's analysis module says what they hold.

``trial_kind`` is ``main``, ``catch``, ``instructed`` (an instructed-response check: the
trial's text said which answer to give) or ``repeat`` (practice trials are not exported);
only ``main`` rows are judgements. ``is_catch`` marks a catch clip and ``catch_passed``
whether the trial's check was passed;
``duration`` is the clip's length in seconds. Crowd-platform ids (``PROLIFIC_PID``,
``workerId``, ... as the platform sent them) follow ``participant`` when a study has them.
An optional ``simulated`` column (true/false) marks the answers of simulated participants
(bots, and every row of :mod:`analysis.simulate`); reports say so.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pandas as pd

RESPONSE_COLUMNS = (
    "study",
    "study_type",
    "participant",
    "participant_seed",
    "trial",
    "trial_id",
    "action",
    "stimulus",
    "stimulus_token",
    "source",
    "motion_hash",
    "video_hash",
    "duration",
    "position",
    "n_items",
    "trial_kind",
    "is_catch",
    "rank",
    "rating",
    "judged_real",
    "choice",
    "catch_passed",
    "plays",
    "time_ms",
    "shown_at",
    "answered_at",
    "completed",
)

# Columns holding whole numbers that may be missing (an unanswered trial has no time).
INTEGER_COLUMNS = (
    "participant",
    "participant_seed",
    "trial",
    "trial_id",
    "stimulus",
    "position",
    "n_items",
    "rank",
    "rating",
    "plays",
    "time_ms",
)
# Columns holding true/false that may be missing (a clip that is no catch has no check).
BOOLEAN_COLUMNS = ("is_catch", "judged_real", "catch_passed", "completed")


class AnalysisError(ValueError):
    """A response table cannot be analysed as asked."""


def require_columns(table: pd.DataFrame, columns, what: str = "this analysis") -> None:
    """Raise :class:`AnalysisError` naming every column of ``columns`` missing from ``table``."""
    missing = [name for name in columns if name not in table.columns]
    if missing:
        raise AnalysisError(
            f"{what} needs the column(s) {', '.join(missing)}; "
            f"the table has: {', '.join(map(str, table.columns)) or 'no columns'}"
        )


def ranked_judgements(table: pd.DataFrame, columns=("participant", "source", "rank", "n_items")):
    """Return ``columns`` of the rows of ``table`` that carry a rank, checked, ranks integer.

    Rows without a rank are clips nobody ranked and are dropped; a rank that is not a
    whole number in ``1..n_items`` raises :class:`AnalysisError`.
    """
    require_columns(table, columns, "rank analysis")
    rows = table.loc[table["rank"].notna(), list(columns)].copy()
    blank = [name for name in columns if name != "rank" and rows[name].isna().any()]
    if blank:
        raise AnalysisError(f"ranked rows with no value in: {', '.join(blank)}")
    ranks = pd.to_numeric(rows["rank"], errors="coerce")
    n_items = pd.to_numeric(rows["n_items"], errors="coerce")
    bad = ranks.isna() | (ranks % 1 != 0) | (ranks < 1) | n_items.isna() | (ranks > n_items)
    if bad.any():
        examples = rows.loc[bad, ["rank", "n_items"]].head(3).to_dict("records")
        raise AnalysisError(
            f"{int(bad.sum())} row(s) have a rank outside 1..n_items, e.g. {examples}"
        )
    rows["rank"] = ranks.astype(int)
    rows["n_items"] = n_items.astype(int)
    return rows


# A spreadsheet runs a cell starting with one of these as a formula (=HYPERLINK(...)).
FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")


def neutralise_formulas(table: pd.DataFrame) -> pd.DataFrame:
    """Return ``table`` with every text cell a spreadsheet would run as a formula
    prefixed with ``'`` (OWASP's advice for CSV injection); numbers are left alone."""
    out = table.copy()
    for name in out.columns:
        column = out[name]
        if (column.dtype == object or pd.api.types.is_string_dtype(column)
                or isinstance(column.dtype, pd.CategoricalDtype)):
            # A plain boolean array: mapping a categorical column gives a categorical
            # of booleans, which has no ``any``.
            text = np.fromiter((isinstance(v, str) and v.startswith(FORMULA_STARTS)
                                for v in column.to_numpy(dtype=object)), dtype=bool, count=len(column))
            if text.any():
                values = column.to_numpy(dtype=object).copy()
                values[text] = ["'" + v for v in values[text]]
                out[name] = pd.Series(values, index=column.index, name=name)
    return out


def write_responses(table: pd.DataFrame, path) -> Path:
    """Write ``table`` to ``path``: Parquet when it ends in ``.parquet``, CSV otherwise.

    In a CSV, text cells that a spreadsheet would run as formulas (crowd ids, comments
    starting with ``= + - @``, a tab or a carriage return) are written with a leading
    ``'`` so that they open as text.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.suffix.lower() == ".parquet":
        if importlib.util.find_spec("pyarrow") is None:
            raise AnalysisError(f"writing {path} needs pyarrow; pip install pyarrow or use .csv")
        table.to_parquet(path, index=False)
    else:
        neutralise_formulas(table).to_csv(path, index=False)
    return path


def read_responses(path) -> pd.DataFrame:
    """Read a response table written by :func:`write_responses`."""
    path = Path(path)
    if not path.is_file():
        raise AnalysisError(f"no response table at {path}")
    if path.suffix.lower() == ".parquet":
        return pd.read_parquet(path)
    table = pd.read_csv(path)
    for name in INTEGER_COLUMNS:
        if name in table.columns and pd.api.types.is_numeric_dtype(table[name]):
            try:
                table[name] = table[name].astype("Int64")
            except (TypeError, ValueError):
                pass  # fractional values: leave the column as the file has it
    for name in BOOLEAN_COLUMNS:
        if name in table.columns:
            try:
                table[name] = as_boolean(table[name], name)
            except AnalysisError:
                pass  # not true/false: leave the column as the file has it
    return table


_TRUTH = {"true": True, "false": False, "1": True, "0": False, "yes": True, "no": False}


def as_boolean(values: pd.Series, name: str) -> pd.Series:
    """Return ``values`` as a nullable boolean column, reading ``True``/``"true"``/``1`` alike."""
    if pd.api.types.is_bool_dtype(values):
        return values.astype("boolean")
    present = values.dropna()
    if pd.api.types.is_numeric_dtype(present) and present.isin([0, 1]).all():
        return values.astype("Float64").astype("boolean")
    words = present.astype(str).str.strip().str.lower()
    unknown = sorted(set(words) - set(_TRUTH))
    if unknown:
        raise AnalysisError(f"column {name} must be true/false or empty; found {', '.join(unknown[:3])}")
    out = pd.Series(pd.NA, index=values.index, dtype="boolean")
    out[present.index] = words.map(_TRUTH).astype(bool)
    return out
