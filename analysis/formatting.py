"""How numbers are written in reports, tables and the methods paragraph."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd


def p_value(p) -> str:
    """Return ``p`` as a paper writes it: ``p < .001``-style ``<0.001`` or three decimals."""
    if p is None or not np.isfinite(p):
        return "n/a"
    return "<0.001" if p < 0.001 else f"{p:.3f}"


def p_text(p) -> str:
    """Return ``p`` for a sentence: ``p < 0.001`` or ``p = 0.123``."""
    shown = p_value(p)
    return f"p {shown[0]} {shown[1:]}" if shown.startswith("<") else f"p = {shown}"


def bootstrap_text(config) -> str:
    """Return how worth intervals were obtained, for the methods paragraph."""
    if config.bootstrap <= 0:
        return "without intervals (the bootstrap was switched off)"
    return (f"with {config.confidence:.0%} percentile intervals from {config.bootstrap} bootstrap "
            f"resamples of participants")


def participant_bootstrap_text(config) -> str:
    """Return how intervals over participants were obtained, for the methods paragraph."""
    if config.bootstrap <= 0:
        return "without intervals (the bootstrap was switched off)"
    return (f"with a {config.confidence:.0%} percentile interval from {config.bootstrap} "
            f"bootstrap resamples of participants")


def number(value, digits: int = 3) -> str:
    """Return ``value`` with ``digits`` decimals, or ``n/a``."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "n/a"
    return f"{value:.{digits}f}"


def interval(low, high, digits: int = 3) -> str:
    """Return ``[low, high]``."""
    return f"[{number(low, digits)}, {number(high, digits)}]"


def estimate_with_interval(value, low, high, digits: int = 3) -> str:
    """Return ``value [low, high]``, all three with ``digits`` decimals (rounding keeps
    their order, so an interval that holds its estimate still does when printed); just
    ``value`` when the interval is missing."""
    shown = number(value, digits)
    if not (_finite(low) and _finite(high)):
        return shown
    return f"{shown} {interval(low, high, digits)}"


def contains(value, low, high) -> bool:
    """Return whether ``low <= value <= high`` (all finite)."""
    return _finite(value) and _finite(low) and _finite(high) and low <= value <= high


def plural(n, word: str, many: str | None = None) -> str:
    """Return ``n`` and ``word`` in the right number: ``1 participant``, ``2 participants``
    (``many`` for an irregular plural: ``plural(2, "was", "were")``)."""
    return f"{n} {word if n == 1 else (many or word + 's')}"


def word_list(items) -> str:
    """Return ``a``, ``a and b``, or ``a, b and c``."""
    items = [str(item) for item in items if str(item)]
    if len(items) < 2:
        return "".join(items)
    return ", ".join(items[:-1]) + " and " + items[-1]


def _finite(value) -> bool:
    try:
        return value is not None and math.isfinite(float(value))
    except (TypeError, ValueError):
        return False


def display_frame(frame: pd.DataFrame) -> pd.DataFrame:
    """Return ``frame`` with its index as columns and numbers as strings for display.

    Columns named ``p`` or ``p_*`` are p-values; other floats get three decimals,
    whole numbers none; missing values print as empty cells.
    """
    frame = frame.reset_index() if _named_index(frame) else frame.reset_index(drop=True)
    out = pd.DataFrame(index=frame.index)
    for name in frame.columns:
        column = frame[name]
        if str(name) == "p" or str(name).startswith("p_"):
            out[name] = [p_value(v) if pd.notna(v) else "" for v in column]
        elif pd.api.types.is_bool_dtype(column):
            out[name] = column.map({True: "yes", False: "no"}).fillna("")
        elif pd.api.types.is_integer_dtype(column):
            out[name] = [str(int(v)) if pd.notna(v) else "" for v in column]
        elif pd.api.types.is_float_dtype(column):
            whole = column.dropna()
            if len(whole) and (whole % 1 == 0).all() and str(name).startswith("n"):
                out[name] = [str(int(v)) if pd.notna(v) else "" for v in column]
            else:
                out[name] = [number(float(v)) if pd.notna(v) else "" for v in column]
        else:
            out[name] = [str(v) if pd.notna(v) else "" for v in column]
    return out


def _named_index(frame) -> bool:
    return any(name is not None for name in frame.index.names)
