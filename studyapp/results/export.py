"""Export a study's answers as tables for :mod:`analysis`: one row per judgement and
criterion (:func:`responses_frame`) and one row per participant (:func:`participants_frame`).

The answer columns of a row come from the study's type (``StudyType.export_values``);
every registered type's columns are in every export (blank where another type's), so a
table's columns do not depend on which studies exist.
"""

from __future__ import annotations

from collections import defaultdict

import pandas as pd
from django.core.management.base import CommandError
from django.db import DatabaseError
from django.db.models import Count

from analysis.tables import INTEGER_COLUMNS, RESPONSE_COLUMNS

from studyapp.participation.bots import is_simulated
from studyapp.participation.forms import DemographicsForm
from studyapp.survey.models import Participant, Stimulus, Study, Trial, TrialItem
from studyapp.survey.study_types import get_study_type, list_study_types

# Response-table column -> TrialItem lookup, for the columns read straight from the database.
LOOKUPS = {
    "participant": "trial__participant_id",
    "participant_seed": "trial__participant__seed",
    "trial": "trial__index",
    "trial_id": "trial_id",
    "action": "trial__action",
    "prompt": "trial__prompt",
    "stimulus": "stimulus_id",
    "stimulus_token": "stimulus__token",
    "source": "stimulus__source",
    "stimulus_role": "stimulus__role",
    "motion_hash": "stimulus__motion_hash",
    "video_hash": "stimulus__video_hash",
    "checkpoint": "stimulus__checkpoint",
    "training_seed": "stimulus__training_seed",
    "duration": "stimulus__duration",
    "position": "position",
    "trial_kind": "trial__kind",
    "catch_passed": "trial__catch_passed",
    "plays": "plays",
    "time_ms": "trial__time_ms",
    "shown_at": "trial__shown_at",
    "answered_at": "trial__answered_at",
    "fetched_at": "fetched_at",
}
READ = {"item_answers": "answers", "trial_answers": "trial__answers", "events": "trial__events",
        "external": "trial__participant__external_ids",
        "completed_at": "trial__participant__completed_at",
        "outcome": "trial__participant__outcome",
        "user_agent": "trial__participant__user_agent"}
# Columns beyond analysis.tables.RESPONSE_COLUMNS, in this order, before the types' own.
EXTRA_COLUMNS = ("criterion", "prompt", "stimulus_role", "checkpoint", "training_seed", "outcome",
                 "simulated", "fetched_at", "n_events", "page_hidden", "window_blurs", "events")
NULLABLE_BOOLEANS = ("judged_real", "catch_passed")


def answer_columns() -> list[str]:
    """Return every registered study type's export columns, once each, in registry order."""
    out = []
    for name in list_study_types():
        out += [c for c in get_study_type(name).export_columns if c not in out]
    return out


def get_study(slug: str) -> Study:
    """Return the study called ``slug``, or raise a ``CommandError`` listing the slugs."""
    try:
        return Study.objects.get(slug=slug)
    except DatabaseError as error:
        raise CommandError(f"Cannot read the study database ({error}); run migrate?") from None
    except Study.DoesNotExist:
        slugs = sorted(Study.objects.values_list("slug", flat=True))
        known = f"known studies: {', '.join(slugs)}" if slugs else "there are no studies yet"
        raise CommandError(f"Unknown study {slug!r}; {known}.") from None


def _event_counts(events) -> dict:
    names = [event[1] for event in events or []
             if isinstance(event, list) and len(event) in (3, 4)]
    return {"n_events": len(names), "page_hidden": names.count("hidden"),
            "window_blurs": names.count("blur")}


def responses_frame(study: Study) -> pd.DataFrame:
    """Return one row per judgement of ``study`` and criterion, by participant, trial,
    position.

    A judgement is a judged clip of an answered trial, whatever the study type; practice
    trials are left out, catch, instructed and repeated trials kept with their
    ``trial_kind`` (and ``catch_passed``: the check passed), which the analysis leaves
    out of the judgements.
    Reference and example clips are never judgements, so never rows. Crowd-platform ids
    (``Participant.external_ids``) become columns right after ``participant``; times are
    ISO 8601 strings; ``events`` is the page's log of the trial as JSON
    (``[[ms, event, position], ...]``; a ``fallback`` event, the in-page player's trial
    gone back to its videos, adds its message), summarised in ``n_events``,
    ``page_hidden`` and ``window_blurs``; ``simulated`` marks the answers of bots
    (``simulate_participants``).
    """
    import json

    kind = study.kind
    criteria = [c.key for c in kind.criteria(study)]
    items = TrialItem.objects.judged().filter(trial__participant__study=study)
    n_items = dict(items.order_by().values_list("trial_id").annotate(n=Count("id")))
    rows = list(
        items.filter(trial__answered_at__isnull=False)
        .exclude(trial__kind=Trial.Kind.PRACTICE)
        .order_by("trial__participant_id", "trial__index", "position")
        .values(*READ.values(), *LOOKUPS.values())
    )
    by_trial = defaultdict(list)
    for row in rows:
        by_trial[row["trial_id"]].append(
            {"position": row["position"], "stimulus": row["stimulus_id"],
             "source": row["stimulus__source"]})
    external = sorted({key for row in rows for key in (row[READ["external"]] or {})})
    rename = {key: key if key not in RESPONSE_COLUMNS else f"external_{key}" for key in external}
    records = []
    for row in rows:
        base = {name: row[lookup] for name, lookup in LOOKUPS.items()}
        for key, value in (row[READ["external"]] or {}).items():
            base[rename[key]] = value
        events = row[READ["events"]] or []
        base.update(
            study=study.slug,
            study_type=study.study_type,
            n_items=n_items[row["trial_id"]],
            is_catch=row["stimulus__role"] == Stimulus.Role.CATCH,
            completed=row[READ["completed_at"]] is not None,
            outcome=row[READ["outcome"]],
            simulated=is_simulated(row[READ["user_agent"]]),
            shown_at=_iso(base["shown_at"]),
            answered_at=_iso(base["answered_at"]),
            fetched_at=_iso(base["fetched_at"]),
            events=json.dumps(events, separators=(",", ":")),
            **_event_counts(events),
        )
        item = {"position": row["position"], "stimulus": row["stimulus_id"],
                "source": row["stimulus__source"]}
        for criterion in criteria:
            record = dict(base, criterion=criterion)
            record.update(kind.export_values(
                (row[READ["trial_answers"]] or {}).get(criterion),
                (row[READ["item_answers"]] or {}).get(criterion),
                item, by_trial[row["trial_id"]],
            ))
            records.append(record)

    answers = [c for c in answer_columns() if c not in RESPONSE_COLUMNS]
    columns = list(RESPONSE_COLUMNS) + list(EXTRA_COLUMNS) + answers
    after = columns.index("participant") + 1
    columns[after:after] = [rename[key] for key in external]
    table = pd.DataFrame.from_records(records, columns=columns)
    for name in set(INTEGER_COLUMNS) | {"rating", "training_seed", "n_events", "page_hidden",
                                        "window_blurs"}:
        table[name] = table[name].astype("Int64")
    for name in NULLABLE_BOOLEANS:
        table[name] = table[name].astype("boolean")
    for name in ("completed", "is_catch", "simulated"):
        table[name] = table[name].astype(bool)
    return table


PARTICIPANT_COLUMNS = (
    "study",
    "participant",
    "participant_seed",
    "started",
    "consented_at",
    "completed",
    "completed_at",
    "outcome",
    "simulated",
    "completion_code",
    "n_judgements",
    "n_catch",
    "failed_catch",
    "n_repeat",
    "inconsistent_repeats",
)


def participants_frame(study: Study) -> pd.DataFrame:
    """Return one row per participant of ``study``: ids, times, outcome, checks, demographics.

    ``outcome`` is ``completed``, ``failed_attention`` (the study's catch rule, decided
    after the last answer), ``no_consent``, ``screened_out``, ``timed_out`` or blank
    (still taking part); ``completion_code`` the code they were given.
    ``n_catch`` and ``failed_catch`` count the attention checks answered and failed
    (catch and instructed trials alike, as ``max_failed_catch`` does),
    ``inconsistent_repeats`` repeated trials answered differently; ``simulated`` marks a bot
    of ``simulate_participants`` (its demographics are random). Crowd-platform ids follow ``participant``; the
    demographic answers (blank when not asked or not given) come last.
    """
    participants = list(Participant.objects.with_checks().filter(study=study).order_by("pk"))
    external = sorted({key for p in participants for key in (p.external_ids or {})})
    external = [k if k not in PARTICIPANT_COLUMNS else f"external_{k}" for k in external]
    demographic = list(DemographicsForm.base_fields)
    records = []
    for p in participants:
        record = {
            "study": study.slug,
            "participant": p.pk,
            "participant_seed": p.seed,
            "started": _iso(p.created_at),
            "consented_at": _iso(p.consented_at),
            "completed": p.completed_at is not None,
            "completed_at": _iso(p.completed_at),
            "outcome": p.outcome,
            "simulated": is_simulated(p.user_agent),
            "completion_code": p.completion_code,
            "n_judgements": p.n_judgements,
            "n_catch": p.n_catch,
            "failed_catch": p.failed_catch,
            "n_repeat": p.n_repeat,
            "inconsistent_repeats": p.inconsistent_repeats,
        }
        for key, value in (p.external_ids or {}).items():
            record[key if key not in PARTICIPANT_COLUMNS else f"external_{key}"] = value
        record.update({name: (p.demographics or {}).get(name, "") for name in demographic})
        records.append(record)
    columns = list(PARTICIPANT_COLUMNS)
    columns[2:2] = external
    table = pd.DataFrame.from_records(records, columns=columns + demographic)
    for name in ("participant", "participant_seed", *PARTICIPANT_COLUMNS[-5:]):
        table[name] = table[name].astype("Int64")
    table["completed"] = table["completed"].astype(bool)
    table["simulated"] = table["simulated"].astype(bool)
    return table


def _iso(moment) -> str | None:
    return moment.isoformat() if moment is not None else None
