"""An arena: a standing study of sources judged in pairs over a fixed set of prompts, to
which sources are added later (``arena add``) and from which they are retired (``arena
retire``); its public leaderboard is :mod:`studyapp.results.arena`.

An arena is a study with ``arena`` settings (``study.arena: {...}`` in its config) and
``design: adaptive``, of a type whose analysis has a worth model of pairs (the adaptive
design's condition), so that the design aims the next pairs at what is least known: a
source just added has no comparisons and the widest posterior. Its settings:

- ``min_votes``: judgements of a source below which the leaderboard calls its score
  preliminary;
- ``real``: the source of real motion capture, shown on the leaderboard as an anchor;
- ``baseline``: a fixed source (a published model, say), shown as an anchor;
- ``refresh_seconds``: how old the leaderboard may get while answers come in before it
  is computed again (in the background).

What changes while the arena stands (sources added and retired, the leaderboard) is in
``Study.arena_state``, which a rebuild of the study's config leaves alone. A retired
source is never planned into a trial again (:func:`retired`, read by the assignment);
its clips, answers and scores stay.
"""

from __future__ import annotations

DEFAULTS = {"min_votes": 30, "real": "real", "baseline": None, "refresh_seconds": 60}


def is_arena(study) -> bool:
    return bool(study.arena)


def settings(study) -> dict:
    return {**DEFAULTS, **(study.arena or {})}


def retired(study) -> list[str]:
    """Return the names of the study's retired sources."""
    return sorted(((study.arena_state or {}).get("retired") or {}) if study.arena else {})


def check(arena, design: str, supported: bool, stop_when=None) -> tuple[dict, str | None]:
    """Return the arena settings with their defaults and what is wrong with them (or None).

    ``supported``: whether the study type offers an adaptive design of pairs;
    ``stop_when``: the study's stopping rule (an arena stands: it has none)."""
    if arena in (None, {}, False):
        return {}, None
    if arena is True:
        arena = {}
    if not isinstance(arena, dict):
        return {}, f"arena: {arena!r} must be a mapping like {{min_votes: 30, baseline: NAME}}"
    for name, value in arena.items():
        if name not in DEFAULTS:
            return {}, f"arena.{name}: not a setting (settings: {', '.join(DEFAULTS)})"
        if name in ("min_votes", "refresh_seconds") and (
                not isinstance(value, int) or isinstance(value, bool) or value < 0):
            return {}, f"arena.{name}: {value!r} must be a whole number of at least 0"
        if name in ("real", "baseline") and value is not None and not (
                isinstance(value, str) and value):
            return {}, f"arena.{name}: {value!r} must be a source's name (or null)"
    if not supported:
        return {}, "arena: needs a type with a worth model of pairs (its adaptive design)"
    if stop_when:
        return {}, ("arena: an arena stands while sources join and leave, so it takes no "
                    "stopping rule; remove study.stop_when (or make it a study that is not an "
                    "arena)")
    if design != "adaptive":
        return {}, ("arena: an arena runs an adaptive design, so that a source added later is "
                    "brought up to precision first; set design: adaptive")
    return {**DEFAULTS, **arena}, None
