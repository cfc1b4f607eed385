"""Exclusion rules: which participants and trials the statistics leave out, counted.

Rules, in order:

1. (optional) participants who did not complete the study;
2. participants who failed more than ``max_failed_catch`` attention checks (catch
   trials and instructed checks: every graded trial but the repeats): all their
   judgements go;
2b. (optional, ``max_failed_repeats``) participants who answered more than that many
   repeated trials differently the second time: all their judgements go. Counted
   (with 0) but not applied by default: between two equally good clips a person may
   fairly choose differently, so a changed repeat is a reliability figure (the
   quality table) more than an attention check;
3. trials answered faster than ``min_time_factor`` times the length of their longest
   clip (``time_ms < factor * duration * 1000``): the trial goes. Skipped, with a note,
   when the table has no clip durations.

Every rule is counted even when exclusions are off, so a report can say what they
would have removed.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

COLUMNS = ["rule", "applied", "excludes", "participants", "trials", "judgements"]


def apply(rows: pd.DataFrame, config) -> tuple[pd.DataFrame, pd.DataFrame, list[str]]:
    """Return the rows kept, the exclusion table and notes.

    ``rows`` holds every trial kind with ``pcode``, ``trial_key``, ``trial_kind``,
    ``catch_passed`` and, when known, ``time_ms``, ``duration`` and ``completed``. The
    table counts main-trial judgements (catch and repeat trials never enter the
    statistics); ``participants`` is how many participants a rule touches.
    """
    main = (rows["trial_kind"] == "main").to_numpy() & ~rows["is_catch"].to_numpy()
    notes = []
    records = [_count("Main-trial judgements before exclusions", "", rows, main, "")]
    keep = np.ones(len(rows), dtype=bool)

    if config.completed_only:
        if "completed" in rows.columns:
            flagged = ~rows["completed"].fillna(False).to_numpy(dtype=bool)
            records.append(_count("Did not complete the study", "yes", rows, main & flagged))
            keep &= ~flagged
        else:
            notes.append("the table has no 'completed' column: all participants were kept")

    failed = rows["catch_passed"].eq(False).fillna(False).to_numpy(dtype=bool)
    kind = rows["trial_kind"].to_numpy()
    # Catch trials: every graded trial but the repeats (a table without ``trial_kind``
    # has its catch results and nothing else graded).
    flagged = _failing(rows, failed & (kind != "repeat"), config.max_failed_catch)
    label = catch_rule(config.max_failed_catch)
    records.append(_count(label, _applied(config), rows, main & flagged))
    if config.exclusions:
        keep &= ~flagged

    limit = config.max_failed_repeats
    flagged = _failing(rows, failed & (kind == "repeat"), 0 if limit is None else limit)
    label = repeat_rule(0 if limit is None else limit)
    if limit is None:
        applied = "no (counted only; --max-failed-repeats N applies it)"
    else:
        applied = _applied(config)
    records.append(_count(label, applied, rows, main & flagged))
    if config.exclusions and limit is not None:
        keep &= ~flagged

    speed = speed_rule(config.min_time_factor)
    has_duration = "duration" in rows.columns and rows["duration"].notna().any()
    has_time = "time_ms" in rows.columns and rows["time_ms"].notna().any()
    if not (has_duration and has_time):
        missing = "clip durations ('duration')" if not has_duration else "answer times ('time_ms')"
        notes.append(f"the table has no {missing}: the rule on answering faster than the clip "
                     f"length was skipped")
        records.append({"rule": speed, "applied": "skipped (no data)", "excludes": "trials",
                        "participants": 0, "trials": 0, "judgements": 0})
    else:
        duration = pd.to_numeric(rows["duration"], errors="coerce")
        longest = duration.groupby(rows["trial_key"].to_numpy()).transform("max").to_numpy()
        time_ms = pd.to_numeric(rows["time_ms"], errors="coerce").to_numpy(dtype=float)
        with np.errstate(invalid="ignore"):
            fast = time_ms < config.min_time_factor * longest * 1000.0
        unknown = int(np.count_nonzero(main & (np.isnan(time_ms) | np.isnan(longest))))
        if unknown:
            notes.append(f"{unknown} judgement(s) with no answer time or clip duration were kept")
        records.append(_count(speed, _applied(config), rows, main & fast & keep, "trials"))
        if config.exclusions:
            keep &= ~fast

    records.append(_count("Analysed", "", rows, main & keep, ""))
    return rows.loc[keep], pd.DataFrame(records, columns=COLUMNS), notes


def catch_rule(limit: int) -> str:
    """Return the attention-check rule in words: ``Failed an attention check`` (limit 0),
    ``Failed more than one attention check``, ``... more than 2 attention checks``."""
    return f"Failed {_more_than(limit, 'attention check')}"


def repeat_rule(limit: int) -> str:
    """Return the repeated-trials rule in words."""
    return f"Answered {_more_than(limit, 'repeated trial')} differently"


def speed_rule(factor: float) -> str:
    """Return the answer-time rule in words."""
    if factor == 1:
        return "Answered before the longest clip of the trial could have played once"
    return f"Answered in less than {factor:g} times the length of the trial's longest clip"


def _more_than(limit: int, noun: str) -> str:
    if limit == 0:
        return f"an {noun}" if noun[0] in "aeiou" else f"a {noun}"
    if limit == 1:
        return f"more than one {noun}"
    return f"more than {limit} {noun}s"


def _failing(rows, failed, limit: int):
    """Return the rows of participants with more than ``limit`` failed trials."""
    per_participant = pd.Series(rows["trial_key"].to_numpy()[failed]).groupby(
        rows["pcode"].to_numpy()[failed]).nunique()
    return rows["pcode"].isin(per_participant.index[per_participant > limit]).to_numpy()


def _applied(config) -> str:
    return "yes" if config.exclusions else "no (--no-exclusions)"


def _count(rule, applied, rows, mask, excludes="participants") -> dict:
    """Count a rule; ``excludes`` says what it removes: whole ``participants`` or ``trials``."""
    return {
        "rule": rule,
        "applied": applied,
        "excludes": excludes,
        "participants": int(pd.unique(rows["pcode"].to_numpy()[mask]).size),
        "trials": int(pd.unique(rows["trial_key"].to_numpy()[mask]).size),
        "judgements": int(np.count_nonzero(mask)),
    }
