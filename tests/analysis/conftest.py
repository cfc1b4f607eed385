"""Factories of small response tables, written out trial by trial."""

import pandas as pd

from analysis.registry import get_analysis
from analysis.study import AnalysisConfig
from analysis.tables import RESPONSE_COLUMNS


def trial(participant, clips, action="eat", kind="main", time_ms=9000, choice=None,
          catch_passed=None, duration=2.0):
    """Return one trial: ``clips`` are ``(source, answer)`` or ``(source, answer, stimulus)``."""
    return dict(participant=participant, clips=clips, action=action, kind=kind, time_ms=time_ms,
                choice=choice, catch_passed=catch_passed, duration=duration)


def make_table(study_type, trials, study="test"):
    """Return a response table with one row per clip of ``trials`` (see :func:`trial`):
    a clip's answer goes to the type's answer column, a trial's ``choice`` to ``choice``."""
    column = get_analysis(study_type).answer
    rows = []
    counters = {}
    for trial_id, spec in enumerate(trials, start=1):
        index = counters.get(spec["participant"], 0)
        counters[spec["participant"]] = index + 1
        for position, clip in enumerate(spec["clips"]):
            source, answer = clip[0], clip[1]
            stimulus = clip[2] if len(clip) > 2 else f"{spec['action']}-{source}"
            row = {name: None for name in RESPONSE_COLUMNS}
            row.update(
                study=study, study_type=study_type, participant=spec["participant"], trial=index,
                trial_id=trial_id, action=spec["action"], stimulus=stimulus, source=source,
                duration=spec["duration"], position=position, n_items=len(spec["clips"]),
                trial_kind=spec["kind"], is_catch=source == "catch", catch_passed=spec["catch_passed"],
                time_ms=spec["time_ms"], completed=True, choice=spec["choice"],
            )
            if answer is not None:
                row[column] = answer
            rows.append(row)
    return pd.DataFrame(rows, columns=list(RESPONSE_COLUMNS))


def config(**changes):
    """Return an analysis configuration with a small bootstrap, for speed."""
    return AnalysisConfig(**{"bootstrap": 200, **changes})
